//! Fuzzing the coordinator-worker frame decoder (cargo-fuzz needs a nightly toolchain; inputs
//! come from the seeded xorshift generator of `bettimill-testkit`, not proptest: every run
//! sees the same inputs, and a failure names the case's seed).
//!
//! Inputs: random byte streams; valid sessions (handshake and messages in both directions)
//! damaged by byte flips, truncation and insertions; and frames with valid lengths but random
//! payloads. Each stream is read through a reader that returns short reads, as pipes do.
//! Properties: `read_frame` never panics, every call consumes at least one byte or ends the
//! stream, so reading a stream to its end always terminates; lengths outside 1..=MAX_FRAME_LEN
//! are refused before any payload buffer is allocated; valid frames decode to what was sent.
//!
//! The test prints how many frames it decoded; `BETTIMILL_FUZZ_CASES=N` multiplies the cases.

use bettimill_executor::protocol::{
    encode_frame, read_frame, FromWorker, Handshake, ProtocolError, Stage, ToWorker, MAX_FRAME_LEN,
};
use bettimill_testkit::{fuzz_scale, Xorshift};
use serde::de::DeserializeOwned;
use std::io::Read;

/// A pipe-like reader: returns at most `chunk` bytes per call.
struct ShortReads<'a> {
    bytes: &'a [u8],
    chunk: usize,
}

impl Read for ShortReads<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = buf.len().min(self.chunk).min(self.bytes.len());
        buf[..n].copy_from_slice(&self.bytes[..n]);
        self.bytes = &self.bytes[n..];
        Ok(n)
    }
}

/// Reads frames of type `T` until the end or an error; returns how many were read.
fn drain<T: DeserializeOwned>(bytes: &[u8], chunk: usize) -> u64 {
    let mut reader = ShortReads { bytes, chunk };
    let mut frames = 0u64;
    loop {
        let before = reader.bytes.len();
        match read_frame::<T>(&mut reader, "peer") {
            Ok(Some(_)) => {
                frames += 1;
                // A decoded frame consumed its 4-byte prefix and a non-empty payload.
                assert!(before - reader.bytes.len() >= 5, "a frame consumed nothing");
            }
            Ok(None) => {
                assert_eq!(before, 0, "end of stream reported with bytes left");
                return frames;
            }
            Err(ProtocolError::BadLength { length, .. }) => {
                assert!(length == 0 || length > MAX_FRAME_LEN);
                return frames;
            }
            Err(_) => return frames,
        }
    }
}

fn valid_session(rng: &mut Xorshift) -> (Vec<u8>, Vec<u8>) {
    let handshake = Handshake {
        protocol_version: rng.next_u64() as u32 % 3,
        tool_version: "0.1.0".into(),
        plan_hash: format!("{:016x}", rng.next_u64()),
    };
    let mut to_worker = encode_frame(&handshake);
    let mut from_worker = encode_frame(&handshake);
    for _ in 0..rng.below(6) {
        let message = if rng.below(4) == 0 {
            ToWorker::Shutdown
        } else {
            ToWorker::Build {
                shard_index: rng.next_u64() >> rng.below(64),
            }
        };
        to_worker.extend(encode_frame(&message));
        let reply = match rng.below(4) {
            0 => FromWorker::Progress {
                shard_index: rng.next_u64(),
                regenerations: rng.next_u64() as u32,
            },
            3 => FromWorker::Stage {
                shard_index: rng.next_u64(),
                sample: rng.next_u64(),
                attempt: rng.next_u64() as u32,
                stage: match rng.below(6) {
                    0 => Stage::Generate,
                    1 => Stage::Deform,
                    2 => Stage::Hypervolume,
                    3 => Stage::Verify,
                    4 => Stage::Downscale {
                        side: rng.next_u64() as u32,
                    },
                    _ => Stage::Encode,
                },
                thousandths: rng.below(1001) as u16,
            },
            1 => FromWorker::Done {
                shard_index: rng.next_u64(),
                regenerations: rng.next_u64(),
                bytes: rng.next_u64(),
            },
            _ => FromWorker::Failed {
                shard_index: rng.next_u64(),
                reason: {
                    let n = rng.below(40);
                    String::from_utf8_lossy(&rng.bytes(n)).into_owned()
                },
            },
        };
        from_worker.extend(encode_frame(&reply));
    }
    (to_worker, from_worker)
}

fn damage(rng: &mut Xorshift, mut bytes: Vec<u8>) -> Vec<u8> {
    for _ in 0..1 + rng.below(4) {
        match rng.below(4) {
            0 if !bytes.is_empty() => {
                let i = rng.below(bytes.len());
                bytes[i] = rng.next_u64() as u8;
            }
            1 => {
                let cut = rng.below(bytes.len() + 1);
                bytes.truncate(cut);
            }
            2 => {
                let at = rng.below(bytes.len() + 1);
                let n = 1 + rng.below(8);
                let extra = rng.bytes(n);
                bytes.splice(at..at, extra);
            }
            _ => {
                // A length prefix with a random (often huge) value.
                let at = rng.below(bytes.len() + 1);
                let length = (rng.next_u64() as u32) >> rng.below(32);
                bytes.splice(at..at, length.to_le_bytes());
            }
        }
    }
    bytes
}

fn all_types(bytes: &[u8], chunk: usize) -> u64 {
    drain::<Handshake>(bytes, chunk)
        + drain::<ToWorker>(bytes, chunk)
        + drain::<FromWorker>(bytes, chunk)
}

#[test]
fn the_frame_decoder_survives_random_and_damaged_streams() {
    let cases = 20_000 * u64::from(fuzz_scale());
    let mut executions = 0u64;
    let mut frames = 0u64;
    for case in 0..cases {
        let mut rng =
            Xorshift(0x9E37_79B9_7F4A_7C15 ^ (case + 1).wrapping_mul(0xBF58_476D_1CE4_E5B9));
        let chunk = 1 + rng.below(9);
        let stream = match case % 3 {
            0 => {
                let n = rng.below(256);
                rng.bytes(n)
            }
            1 => {
                let (to_worker, from_worker) = valid_session(&mut rng);
                // Undamaged, every frame decodes: handshake first, then messages.
                let mut reader = ShortReads {
                    bytes: &to_worker,
                    chunk,
                };
                let first = read_frame::<Handshake>(&mut reader, "coordinator");
                assert!(matches!(first, Ok(Some(_))), "case {case}: {first:?}");
                while let Some(_message) = read_frame::<ToWorker>(&mut reader, "coordinator")
                    .unwrap_or_else(|e| panic!("case {case}: valid frame refused: {e}"))
                {
                    frames += 1;
                }
                let mut joined = to_worker;
                joined.extend(from_worker);
                damage(&mut rng, joined)
            }
            _ => {
                // Valid lengths around the limit with random payloads.
                let length = [1, 2, 5, 17, 255][rng.below(5)];
                let mut bytes = (length as u32).to_le_bytes().to_vec();
                bytes.extend(rng.bytes(length));
                bytes
            }
        };
        frames += all_types(&stream, chunk);
        executions += 3;
    }
    eprintln!("fuzz protocol: {executions} streams decoded, {frames} frames accepted");
}

#[test]
fn oversized_lengths_are_refused_before_reading_the_payload() {
    for length in [0u32, MAX_FRAME_LEN + 1, u32::MAX] {
        // Only the prefix is present: a decoder that tried to read or allocate the payload
        // first would report truncation instead.
        let bytes = length.to_le_bytes();
        let result = read_frame::<ToWorker>(&mut &bytes[..], "worker");
        assert!(
            matches!(result, Err(ProtocolError::BadLength { length: l, .. }) if l == length),
            "{length}: {result:?}"
        );
    }
    let mut at_limit = MAX_FRAME_LEN.to_le_bytes().to_vec();
    at_limit.extend(vec![0u8; 10]);
    let result = read_frame::<ToWorker>(&mut &at_limit[..], "worker");
    assert!(
        matches!(result, Err(ProtocolError::Truncated { .. })),
        "{result:?}"
    );
}
