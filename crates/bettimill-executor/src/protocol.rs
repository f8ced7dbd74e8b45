//! The coordinator-worker protocol (version [`PROTOCOL_VERSION`]).
//!
//! `bettimill build` (the coordinator) starts `bettimill worker --dir DIR` child processes
//! and talks to each over its stdin (coordinator to worker) and stdout (worker to
//! coordinator). Byte layout of both directions: a sequence of frames,
//!
//! ```text
//! frame = length: u32 little-endian (1 ..= MAX_FRAME_LEN) | payload: `length` bytes of postcard
//! ```
//!
//! The first frame in each direction is a [`Handshake`]: postcard of
//! `(protocol_version: varint u32, tool_version: string, plan_hash: string)`. Its layout is
//! frozen for all protocol versions, so that two different builds of bettimill can always
//! tell each other apart and say so instead of misreading each other. Both sides send their
//! handshake first and then check the peer's (see [`check_handshake`]); any difference in
//! protocol version, tool version or plan hash ends the session with an error that tells
//! the user what to do.
//!
//! After the handshake, the coordinator sends [`ToWorker`] frames and the worker answers
//! with [`FromWorker`] frames: for each `Build` request, one `Progress` per finished sample
//! and then exactly one `Done` or `Failed` for that shard. Between them (protocol 3 on), a
//! `Stage` frame says which stage of which sample the worker has started (generate, deform,
//! hypervolume targeting, verify, each downscaled copy, encode) and where that leaves the
//! sample, in thousandths; a worker sends at most one per [`STAGE_INTERVAL`]: of the stages
//! that start in between it keeps the latest and sends it when the interval has passed,
//! unless its sample is done by then (a small sample's stages are mostly never sent), so
//! the frames cost nothing next to the work and never follow their sample's `Progress`.
//! They are for display only: nothing depends on them. The worker writes the shard to
//! the dataset directory itself (atomically), so the coordinator never handles sample bytes.
//!
//! Liveness: from its handshake on, a worker also sends a `Heartbeat` every
//! [`HEARTBEAT_INTERVAL`] from a thread of its own, whatever it is doing, so a sample that
//! takes minutes (a 128^4 sample) still shows a live worker. The coordinator treats a worker
//! that sends no frame at all for its `--worker-timeout` as frozen (stopped, swapped out,
//! deadlocked): it kills it and re-queues its shard. Heartbeats may arrive between any two
//! other frames and carry nothing else.
//!
//! Recovery rules: end of file at a frame boundary means the peer closed the session
//! ([`read_frame`] returns `None`); end of file inside a frame, a length of zero or above
//! [`MAX_FRAME_LEN`], or a payload that does not decode is [`ProtocolError`]. A worker
//! exits when its stdin reaches end of file, which is how an orphaned worker notices that
//! its coordinator died. Any change to [`ToWorker`] or [`FromWorker`] must bump
//! [`PROTOCOL_VERSION`].

pub use bettimill_sample::Stage;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::io::{Read, Write};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};

/// The version of the frame payloads after the handshake.
pub const PROTOCOL_VERSION: u32 = 3;

/// A worker sends at most one [`FromWorker::Stage`] per this interval (protocol 3 on).
pub const STAGE_INTERVAL: std::time::Duration = std::time::Duration::from_millis(250);

/// How often a worker sends [`FromWorker::Heartbeat`] (protocol 2 on).
pub const HEARTBEAT_INTERVAL: std::time::Duration = std::time::Duration::from_secs(1);

/// The largest payload either side accepts (messages are small; this bounds memory when the
/// peer is not a bettimill of this protocol).
pub const MAX_FRAME_LEN: u32 = 1 << 20;

/// The first frame in each direction. Its layout never changes.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Handshake {
    /// [`PROTOCOL_VERSION`] of the sender.
    pub protocol_version: u32,
    /// bettimill version of the sender.
    pub tool_version: String,
    /// The plan hash the sender computed for the dataset.
    pub plan_hash: String,
}

/// Coordinator to worker.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ToWorker {
    /// Generate, verify and write the shard with this index in the plan.
    Build {
        /// The shard's index in the plan.
        shard_index: u64,
    },
    /// Exit after the current shard.
    Shutdown,
}

/// Worker to coordinator.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum FromWorker {
    /// One more sample of the shard is verified.
    Progress {
        /// The shard's index in the plan.
        shard_index: u64,
        /// Regenerations (rejected attempts) this sample needed.
        regenerations: u32,
    },
    /// The shard and its completion record are written.
    Done {
        /// The shard's index in the plan.
        shard_index: u64,
        /// Rejected attempts over the shard.
        regenerations: u64,
        /// Size of the tar in bytes.
        bytes: u64,
    },
    /// The shard could not be built; nothing was written for it.
    Failed {
        /// The shard's index in the plan.
        shard_index: u64,
        /// Why, in words for the user.
        reason: String,
    },
    /// The worker is alive (sent every [`HEARTBEAT_INTERVAL`], independently of its work).
    Heartbeat,
    /// A stage of a sample of the shard starts (protocol 3 on; at most one per
    /// [`STAGE_INTERVAL`]).
    Stage {
        /// The shard's index in the plan.
        shard_index: u64,
        /// The sample's index in the dataset.
        sample: u64,
        /// Its attempt (0 first).
        attempt: u32,
        /// The stage starting.
        stage: Stage,
        /// Where the sample is, in thousandths of the whole (0 to 1000; an estimate, see
        /// `bettimill_sample::Stage::span`).
        thousandths: u16,
    },
}

/// Which side of the session a handshake came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Peer {
    /// The check runs in the coordinator; the peer is a worker.
    Worker,
    /// The check runs in a worker; the peer is the coordinator.
    Coordinator,
}

impl Peer {
    fn names(self) -> (&'static str, &'static str) {
        match self {
            Peer::Worker => ("worker", "coordinator"),
            Peer::Coordinator => ("coordinator", "worker"),
        }
    }
}

/// A broken session.
#[derive(Debug, thiserror::Error)]
pub enum ProtocolError {
    /// Reading or writing the pipe failed.
    #[error("{peer} pipe: {source}")]
    Io {
        /// Which pipe.
        peer: &'static str,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// The stream ended in the middle of a frame.
    #[error("{peer} closed the pipe in the middle of a frame")]
    Truncated {
        /// Which pipe.
        peer: &'static str,
    },
    /// A frame length outside 1..=MAX_FRAME_LEN.
    #[error("{peer} sent a frame of {length} bytes (allowed 1 to {MAX_FRAME_LEN}); it does not speak the bettimill worker protocol")]
    BadLength {
        /// Which pipe.
        peer: &'static str,
        /// The length read.
        length: u32,
    },
    /// A payload that does not decode.
    #[error("{peer} sent an undecodable message ({source}); it does not speak bettimill worker protocol {PROTOCOL_VERSION}: make sure both sides are the same bettimill binary")]
    Decode {
        /// Which pipe.
        peer: &'static str,
        /// The decoder's reason.
        source: postcard::Error,
    },
    /// The two sides are different programs.
    #[error("{peer} is bettimill {theirs} (protocol {their_protocol}), {us} is bettimill {ours} (protocol {our_protocol}): rebuild or reinstall so that both are the same binary, then run the command again")]
    VersionMismatch {
        /// The peer's role.
        peer: &'static str,
        /// Our role.
        us: &'static str,
        /// The peer's tool version.
        theirs: String,
        /// Our tool version.
        ours: String,
        /// The peer's protocol version.
        their_protocol: u32,
        /// Our protocol version.
        our_protocol: u32,
    },
    /// The two sides computed different plans for the directory.
    #[error("{peer} computed plan {theirs}, {us} has plan {ours}: the dataset directory's manifest.toml or build.json changed during the build; restore them or start again in a new --out directory")]
    PlanMismatch {
        /// The peer's role.
        peer: &'static str,
        /// Our role.
        us: &'static str,
        /// The peer's plan hash.
        theirs: String,
        /// Our plan hash.
        ours: String,
    },
}

/// Checks the peer's handshake against ours.
pub fn check_handshake(
    ours: &Handshake,
    theirs: &Handshake,
    peer: Peer,
) -> Result<(), ProtocolError> {
    let (peer, us) = peer.names();
    if ours.protocol_version != theirs.protocol_version || ours.tool_version != theirs.tool_version
    {
        return Err(ProtocolError::VersionMismatch {
            peer,
            us,
            theirs: theirs.tool_version.clone(),
            ours: ours.tool_version.clone(),
            their_protocol: theirs.protocol_version,
            our_protocol: ours.protocol_version,
        });
    }
    if ours.plan_hash != theirs.plan_hash {
        return Err(ProtocolError::PlanMismatch {
            peer,
            us,
            theirs: theirs.plan_hash.clone(),
            ours: ours.plan_hash.clone(),
        });
    }
    Ok(())
}

/// One frame: length prefix and payload.
pub fn encode_frame(message: &impl Serialize) -> Vec<u8> {
    let payload = postcard::to_stdvec(message).expect("protocol messages always serialise");
    let length = u32::try_from(payload.len())
        .ok()
        .filter(|&l| l <= MAX_FRAME_LEN)
        .expect("protocol messages are far below MAX_FRAME_LEN");
    let mut frame = Vec::with_capacity(4 + payload.len());
    frame.extend_from_slice(&length.to_le_bytes());
    frame.extend_from_slice(&payload);
    frame
}

fn decode<T: DeserializeOwned>(payload: &[u8], peer: &'static str) -> Result<T, ProtocolError> {
    postcard::from_bytes(payload).map_err(|source| ProtocolError::Decode { peer, source })
}

fn check_length(length: u32, peer: &'static str) -> Result<usize, ProtocolError> {
    if length == 0 || length > MAX_FRAME_LEN {
        return Err(ProtocolError::BadLength { peer, length });
    }
    Ok(length as usize)
}

/// Writes one frame and flushes.
pub fn write_frame(
    output: &mut impl Write,
    message: &impl Serialize,
    peer: &'static str,
) -> Result<(), ProtocolError> {
    output
        .write_all(&encode_frame(message))
        .and_then(|()| output.flush())
        .map_err(|source| ProtocolError::Io { peer, source })
}

/// Reads one frame; `None` at end of file on a frame boundary.
pub fn read_frame<T: DeserializeOwned>(
    input: &mut impl Read,
    peer: &'static str,
) -> Result<Option<T>, ProtocolError> {
    let mut prefix = [0u8; 4];
    let mut filled = 0;
    while filled < 4 {
        match input.read(&mut prefix[filled..]) {
            Ok(0) if filled == 0 => return Ok(None),
            Ok(0) => return Err(ProtocolError::Truncated { peer }),
            Ok(n) => filled += n,
            Err(err) if err.kind() == std::io::ErrorKind::Interrupted => {}
            Err(source) => return Err(ProtocolError::Io { peer, source }),
        }
    }
    let length = check_length(u32::from_le_bytes(prefix), peer)?;
    let mut payload = vec![0u8; length];
    input.read_exact(&mut payload).map_err(|source| {
        if source.kind() == std::io::ErrorKind::UnexpectedEof {
            ProtocolError::Truncated { peer }
        } else {
            ProtocolError::Io { peer, source }
        }
    })?;
    decode(&payload, peer).map(Some)
}

/// Async [`write_frame`].
pub async fn write_frame_async(
    output: &mut (impl AsyncWrite + Unpin),
    message: &impl Serialize,
    peer: &'static str,
) -> Result<(), ProtocolError> {
    let frame = encode_frame(message);
    async {
        output.write_all(&frame).await?;
        output.flush().await
    }
    .await
    .map_err(|source| ProtocolError::Io { peer, source })
}

/// Async [`read_frame`]. Not cancel-safe: a session whose read is abandoned is over.
pub async fn read_frame_async<T: DeserializeOwned>(
    input: &mut (impl AsyncRead + Unpin),
    peer: &'static str,
) -> Result<Option<T>, ProtocolError> {
    let mut prefix = [0u8; 4];
    let mut filled = 0;
    while filled < 4 {
        match input.read(&mut prefix[filled..]).await {
            Ok(0) if filled == 0 => return Ok(None),
            Ok(0) => return Err(ProtocolError::Truncated { peer }),
            Ok(n) => filled += n,
            Err(source) => return Err(ProtocolError::Io { peer, source }),
        }
    }
    let length = check_length(u32::from_le_bytes(prefix), peer)?;
    let mut payload = vec![0u8; length];
    input.read_exact(&mut payload).await.map_err(|source| {
        if source.kind() == std::io::ErrorKind::UnexpectedEof {
            ProtocolError::Truncated { peer }
        } else {
            ProtocolError::Io { peer, source }
        }
    })?;
    decode(&payload, peer).map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hello(version: &str, plan: &str) -> Handshake {
        Handshake {
            protocol_version: PROTOCOL_VERSION,
            tool_version: version.into(),
            plan_hash: plan.into(),
        }
    }

    #[test]
    fn frames_round_trip_and_end_cleanly() {
        let messages = vec![
            FromWorker::Progress {
                shard_index: 3,
                regenerations: 1,
            },
            FromWorker::Done {
                shard_index: 3,
                regenerations: 7,
                bytes: 1 << 40,
            },
            FromWorker::Failed {
                shard_index: u64::MAX,
                reason: "é".repeat(100),
            },
            FromWorker::Heartbeat,
            FromWorker::Stage {
                shard_index: 3,
                sample: 1 << 35,
                attempt: 2,
                stage: Stage::Downscale { side: 64 },
                thousandths: 1000,
            },
            FromWorker::Stage {
                shard_index: 0,
                sample: 0,
                attempt: 0,
                stage: Stage::Verify,
                thousandths: 300,
            },
        ];
        let mut bytes = Vec::new();
        for m in &messages {
            write_frame(&mut bytes, m, "test").unwrap();
        }
        let mut input = &bytes[..];
        for m in &messages {
            assert_eq!(
                read_frame::<FromWorker>(&mut input, "test")
                    .unwrap()
                    .as_ref(),
                Some(m)
            );
        }
        assert!(read_frame::<FromWorker>(&mut input, "test")
            .unwrap()
            .is_none());
    }

    #[test]
    fn every_stage_round_trips_in_a_stage_frame() {
        for stage in [
            Stage::Generate,
            Stage::Deform,
            Stage::Hypervolume,
            Stage::Verify,
            Stage::Downscale { side: 0 },
            Stage::Downscale { side: u32::MAX },
            Stage::Encode,
        ] {
            let frame = FromWorker::Stage {
                shard_index: 7,
                sample: 12,
                attempt: 15,
                stage,
                thousandths: 999,
            };
            let bytes = encode_frame(&frame);
            assert_eq!(
                read_frame::<FromWorker>(&mut &bytes[..], "test").unwrap(),
                Some(frame)
            );
        }
    }

    #[test]
    fn the_handshake_layout_is_frozen() {
        // protocol_version varint (one byte below 128), then two length-prefixed strings.
        let frame = encode_frame(&hello("0.1.0", "ab"));
        assert_eq!(
            frame,
            [
                10,
                0,
                0,
                0,
                PROTOCOL_VERSION as u8,
                5,
                b'0',
                b'.',
                b'1',
                b'.',
                b'0',
                2,
                b'a',
                b'b'
            ]
        );
    }

    #[test]
    fn damaged_streams_are_errors_not_panics() {
        let frame = encode_frame(&ToWorker::Build { shard_index: 9 });
        for cut in 1..frame.len() {
            let err = read_frame::<ToWorker>(&mut &frame[..cut], "test").unwrap_err();
            assert!(
                matches!(err, ProtocolError::Truncated { .. }),
                "{cut}: {err}"
            );
        }
        let err = read_frame::<ToWorker>(&mut &[0u8, 0, 0, 0][..], "test").unwrap_err();
        assert!(matches!(err, ProtocolError::BadLength { length: 0, .. }));
        let err = read_frame::<ToWorker>(&mut &[255u8, 255, 255, 255][..], "test").unwrap_err();
        assert!(matches!(err, ProtocolError::BadLength { .. }));
        let err = read_frame::<ToWorker>(&mut &[1u8, 0, 0, 0, 200][..], "test").unwrap_err();
        assert!(matches!(err, ProtocolError::Decode { .. }), "{err}");
    }

    #[test]
    fn mismatches_say_what_to_do() {
        let ours = hello("0.2.0", "p");
        check_handshake(&ours, &hello("0.2.0", "p"), Peer::Worker).unwrap();
        let err = check_handshake(&ours, &hello("0.1.0", "p"), Peer::Worker).unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains("worker is bettimill 0.1.0")
                && text.contains("coordinator is bettimill 0.2.0")
                && text.contains("same binary"),
            "{text}"
        );
        let mut other_protocol = hello("0.2.0", "p");
        other_protocol.protocol_version += 1;
        assert!(matches!(
            check_handshake(&ours, &other_protocol, Peer::Coordinator),
            Err(ProtocolError::VersionMismatch {
                peer: "coordinator",
                ..
            })
        ));
        let err = check_handshake(&ours, &hello("0.2.0", "q"), Peer::Worker).unwrap_err();
        assert!(err.to_string().contains("new --out directory"), "{err}");
    }
}
