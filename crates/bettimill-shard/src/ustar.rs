//! Deterministic USTAR writing and a safe USTAR reader.
//!
//! # Byte layout written by [`tar_bytes`]
//!
//! For each member, in the order given: one 512-byte header block, then the data, then
//! zero bytes up to the next multiple of 512. After the last member, two 512-byte zero
//! blocks (the end-of-archive marker). Nothing else: no record padding to 10 KiB, no PAX or
//! GNU extension headers, no directory entries. A member's data therefore starts at
//! `header_offset + 512` and the archive length is
//! `sum(512 + round_up(size, 512)) + 1024`.
//!
//! Header fields (offsets in the block; numbers are zero-padded octal ending in NUL):
//!
//! | offset | len | value |
//! | --- | --- | --- |
//! | 0 | 100 | member name, NUL-padded (the `prefix` field is never used) |
//! | 100 | 8 | mode `0000444` |
//! | 108 / 116 | 8 / 8 | uid / gid `0000000` |
//! | 124 | 12 | size, 11 octal digits (so at most 8 GiB - 1) |
//! | 136 | 12 | mtime `00000000000` (1970-01-01) |
//! | 148 | 8 | checksum: 6 octal digits, NUL, space (sum of header bytes, field as spaces) |
//! | 156 | 1 | typeflag `0` (regular file) |
//! | 157 | 100 | linkname, all NUL |
//! | 257 | 8 | magic `ustar\0` and version `00` |
//! | 265 / 297 | 32 / 32 | uname / gname `bettimill` |
//! | 329 / 337 | 8 / 8 | devmajor / devminor `0000000` |
//! | 345 | 167 | prefix and padding, all NUL |
//!
//! So the bytes depend only on the member names and data: the same members give the same
//! archive on every machine and every run.
//!
//! # Member names
//!
//! Written names obey [`check_member_name`]: at most 100 bytes of `[A-Za-z0-9_./-]`, a
//! relative path without empty, `.` or `..` components, dots only in the last component,
//! and that component of the form `BASE.FIELD` (WebDataset splits at the first dot of the
//! last component, so the sample key `dirs/BASE` never contains a dot).
//!
//! # Reading untrusted archives
//!
//! [`read_tar`] and [`tar_entries`] accept POSIX (`ustar\0`, `00`) and GNU (`ustar `, ` \0`)
//! headers and refuse, with the byte offset of the offending header: a bad checksum, a
//! non-octal number, an absolute name or one with a `..` component, links, devices, FIFOs
//! and extension headers (PAX, GNU long names), a size beyond the bytes present or beyond
//! the caller's limit, a missing end-of-archive marker (so a shard cut at a member boundary
//! is an error, not a shorter shard) and non-zero bytes after the marker. Directory entries
//! are skipped. Nothing is allocated from a header's claims: member data is only ever a
//! slice of bytes already present. [`TarStream`] reads the same way from a reader, one
//! member at a time, and refuses a member over its limit by the header's size.

use crate::ShardError;

/// Size of a tar block.
pub const BLOCK: u64 = 512;

/// Bytes one member of `data_bytes` takes in an archive: its header block and its data
/// padded to whole blocks.
pub fn member_bytes(data_bytes: u64) -> u64 {
    BLOCK + data_bytes.div_ceil(BLOCK) * BLOCK
}

/// Largest member size an 11-digit octal size field can hold.
pub const MAX_USTAR_SIZE: u64 = 0o77777777777;

/// Default limit of [`read_tar`] on one member's size (1 GiB).
pub const DEFAULT_MAX_MEMBER_BYTES: u64 = 1 << 30;

const OWNER: &[u8] = b"bettimill";

/// One file of a shard: its name in the tar and its bytes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Member {
    /// Name inside the tar, such as `train/s000001.npy` or `s000001.json`.
    pub name: String,
    /// The file's bytes.
    pub data: Vec<u8>,
}

impl Member {
    /// A member from a name and bytes.
    pub fn new(name: impl Into<String>, data: impl Into<Vec<u8>>) -> Member {
        Member {
            name: name.into(),
            data: data.into(),
        }
    }
}

/// A member found by [`tar_entries`], borrowing its data from the archive.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TarEntry<'a> {
    /// Name inside the tar (the `prefix` field joined in front, if set).
    pub name: String,
    /// Offset of the member's header block in the archive.
    pub header_offset: u64,
    /// The member's data (`data_offset() == header_offset + 512`).
    pub data: &'a [u8],
}

impl TarEntry<'_> {
    /// Offset of the member's first data byte in the archive.
    pub fn data_offset(&self) -> u64 {
        self.header_offset + BLOCK
    }
}

/// Splits a member name into its WebDataset sample key and field: `train/s01.npy.gz`
/// becomes (`train/s01`, `npy.gz`). Returns `None` when the last path component has no dot.
pub fn split_key(name: &str) -> Option<(&str, &str)> {
    let last_start = name.rfind('/').map_or(0, |i| i + 1);
    let dot = name[last_start..].find('.')? + last_start;
    Some((&name[..dot], &name[dot + 1..]))
}

/// Checks the rules a name must obey to be written (see the module documentation).
pub fn check_member_name(name: &str) -> Result<(), ShardError> {
    check_safe_path(name)?;
    if name.len() > 100 {
        return Err(ShardError::bad_name(
            name,
            format!("{} bytes; at most 100 fit a USTAR name field", name.len()),
        ));
    }
    if let Some(bad) = name
        .chars()
        .find(|&c| !(c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | '/')))
    {
        return Err(ShardError::bad_name(
            name,
            format!("character {bad:?}; only A-Z a-z 0-9 _ - . / are allowed"),
        ));
    }
    let (dirs, last) = match name.rfind('/') {
        Some(i) => (&name[..i], &name[i + 1..]),
        None => ("", name),
    };
    if dirs.contains('.') {
        return Err(ShardError::bad_name(
            name,
            "a directory component contains a dot, so the sample key would contain one",
        ));
    }
    let Some((base, field)) = last.split_once('.') else {
        return Err(ShardError::bad_name(
            name,
            "no extension: the last component must be KEY.FIELD",
        ));
    };
    if base.is_empty() {
        return Err(ShardError::bad_name(
            name,
            "empty sample key before the dot",
        ));
    }
    if base.starts_with("__") {
        return Err(ShardError::bad_name(
            name,
            "keys starting with \"__\" are skipped by WebDataset readers as metadata",
        ));
    }
    if field.split('.').any(str::is_empty) {
        return Err(ShardError::bad_name(name, "empty field between dots"));
    }
    Ok(())
}

/// The checks applied to names read from untrusted archives: non-empty, relative, no
/// `..` component, no NUL or control characters.
fn check_safe_path(name: &str) -> Result<(), ShardError> {
    if name.is_empty() {
        return Err(ShardError::bad_name(name, "empty name"));
    }
    if name.starts_with('/') {
        return Err(ShardError::bad_name(name, "absolute path"));
    }
    if name.chars().any(char::is_control) {
        return Err(ShardError::bad_name(name, "control character in the name"));
    }
    for component in name.split('/') {
        match component {
            ".." => return Err(ShardError::bad_name(name, "\"..\" component")),
            "" | "." if name.ends_with('/') => {
                return Err(ShardError::bad_name(name, "names a directory"))
            }
            "" => return Err(ShardError::bad_name(name, "empty path component")),
            "." => return Err(ShardError::bad_name(name, "\".\" component")),
            _ => {}
        }
    }
    Ok(())
}

fn round_up(n: u64) -> u64 {
    n.div_ceil(BLOCK) * BLOCK
}

/// Length of the archive [`tar_bytes`] writes for members of these sizes.
pub fn tar_len(member_sizes: impl IntoIterator<Item = u64>) -> u64 {
    member_sizes
        .into_iter()
        .map(|size| BLOCK + round_up(size))
        .sum::<u64>()
        + 2 * BLOCK
}

fn put_octal(field: &mut [u8], value: u64) {
    let digits = field.len() - 1;
    let text = format!("{value:0digits$o}");
    debug_assert_eq!(text.len(), digits, "value {value} too large for its field");
    field[..digits].copy_from_slice(text.as_bytes());
    field[digits] = 0;
}

/// The header block [`tar_bytes`] writes for a member of this name and size.
pub fn header_block(name: &str, size: u64) -> Result<[u8; 512], ShardError> {
    check_member_name(name)?;
    if size > MAX_USTAR_SIZE {
        return Err(ShardError::MemberTooLarge {
            name: name.to_string(),
            bytes: size,
            limit: MAX_USTAR_SIZE,
        });
    }
    let mut header = [0u8; 512];
    header[..name.len()].copy_from_slice(name.as_bytes());
    put_octal(&mut header[100..108], 0o444);
    put_octal(&mut header[108..116], 0);
    put_octal(&mut header[116..124], 0);
    put_octal(&mut header[124..136], size);
    put_octal(&mut header[136..148], 0);
    header[156] = b'0';
    header[257..263].copy_from_slice(b"ustar\0");
    header[263..265].copy_from_slice(b"00");
    header[265..265 + OWNER.len()].copy_from_slice(OWNER);
    header[297..297 + OWNER.len()].copy_from_slice(OWNER);
    put_octal(&mut header[329..337], 0);
    put_octal(&mut header[337..345], 0);
    header[148..156].fill(b' ');
    let sum: u64 = header.iter().map(|&b| b as u64).sum();
    header[148..156].copy_from_slice(format!("{sum:06o}\0 ").as_bytes());
    Ok(header)
}

/// Writes members, in the given order, as deterministic USTAR bytes (see the module
/// documentation for the exact layout).
pub fn tar_bytes(members: &[Member]) -> Result<Vec<u8>, ShardError> {
    let total = tar_len(members.iter().map(|m| m.data.len() as u64));
    let mut out = Vec::with_capacity(total as usize);
    for member in members {
        out.extend_from_slice(&header_block(&member.name, member.data.len() as u64)?);
        out.extend_from_slice(&member.data);
        out.resize(round_up(out.len() as u64) as usize, 0);
    }
    out.resize(out.len() + 2 * BLOCK as usize, 0);
    debug_assert_eq!(out.len() as u64, total);
    Ok(out)
}

fn parse_octal(field: &[u8], offset: u64, what: &str) -> Result<u64, ShardError> {
    if field.first().is_some_and(|&b| b & 0x80 != 0) {
        return Err(ShardError::Tar {
            offset,
            reason: format!("{what} uses the GNU base-256 encoding, which is not accepted"),
        });
    }
    let text: &[u8] = {
        let end = field
            .iter()
            .rposition(|&b| b != 0 && b != b' ')
            .map_or(0, |i| i + 1);
        let start = field[..end].iter().position(|&b| b != b' ').unwrap_or(end);
        &field[start..end]
    };
    let mut value: u64 = 0;
    for &b in text {
        if !(b'0'..=b'7').contains(&b) {
            return Err(ShardError::Tar {
                offset,
                reason: format!(
                    "{what} field {:?} is not octal",
                    String::from_utf8_lossy(field)
                ),
            });
        }
        value = value
            .checked_mul(8)
            .and_then(|v| v.checked_add((b - b'0') as u64))
            .ok_or_else(|| ShardError::Tar {
                offset,
                reason: format!("{what} overflows"),
            })?;
    }
    Ok(value)
}

fn c_string(field: &[u8]) -> &[u8] {
    let end = field.iter().position(|&b| b == 0).unwrap_or(field.len());
    &field[..end]
}

/// Reads an untrusted archive into owned members, refusing anything unsafe (see the
/// module documentation); each member may hold at most [`DEFAULT_MAX_MEMBER_BYTES`].
pub fn read_tar(bytes: &[u8]) -> Result<Vec<Member>, ShardError> {
    read_tar_with_limit(bytes, DEFAULT_MAX_MEMBER_BYTES)
}

/// [`read_tar`] with an explicit limit on one member's size.
pub fn read_tar_with_limit(bytes: &[u8], max_member_bytes: u64) -> Result<Vec<Member>, ShardError> {
    Ok(tar_entries(bytes, max_member_bytes)?
        .into_iter()
        .map(|entry| Member {
            name: entry.name,
            data: entry.data.to_vec(),
        })
        .collect())
}

/// Walks an untrusted archive and returns its regular-file members with their offsets,
/// borrowing the data (see the module documentation for what is refused).
pub fn tar_entries(bytes: &[u8], max_member_bytes: u64) -> Result<Vec<TarEntry<'_>>, ShardError> {
    let len = bytes.len() as u64;
    let mut entries = Vec::new();
    let mut pos: u64 = 0;
    loop {
        if pos == len {
            return Err(ShardError::TarTruncated {
                offset: len,
                needed: 2 * BLOCK,
                context: "the end-of-archive marker (two zero blocks) is missing".into(),
            });
        }
        if len - pos < BLOCK {
            return Err(ShardError::TarTruncated {
                offset: len,
                needed: BLOCK - (len - pos),
                context: format!("header block at byte {pos}"),
            });
        }
        let header = &bytes[pos as usize..(pos + BLOCK) as usize];
        if header.iter().all(|&b| b == 0) {
            let second = pos + BLOCK;
            if len - second < BLOCK {
                return Err(ShardError::TarTruncated {
                    offset: len,
                    needed: BLOCK - (len - second),
                    context: format!("second end-of-archive block at byte {second}"),
                });
            }
            let rest = &bytes[second as usize..];
            if let Some(i) = rest.iter().position(|&b| b != 0) {
                return Err(ShardError::Tar {
                    offset: second + i as u64,
                    reason: "non-zero byte after the end-of-archive marker".into(),
                });
            }
            return Ok(entries);
        }
        let entry = parse_header(header, pos)?;
        let data_start = pos + BLOCK;
        if entry.size > max_member_bytes {
            return Err(ShardError::MemberTooLarge {
                name: entry.name,
                bytes: entry.size,
                limit: max_member_bytes,
            });
        }
        let available = len - data_start;
        if entry.size > available {
            return Err(ShardError::TarTruncated {
                offset: len,
                needed: entry.size - available,
                context: format!("data of {:?} (header at byte {pos})", entry.name),
            });
        }
        let padded_end = data_start + round_up(entry.size);
        if padded_end > len {
            return Err(ShardError::TarTruncated {
                offset: len,
                needed: padded_end - len,
                context: format!("padding after {:?}", entry.name),
            });
        }
        match entry.kind {
            EntryKind::File => entries.push(TarEntry {
                name: entry.name,
                header_offset: pos,
                data: &bytes[data_start as usize..(data_start + entry.size) as usize],
            }),
            EntryKind::Directory => {}
        }
        pos = padded_end;
    }
}

/// One member read by [`TarStream::next_entry`]: its name, the offset of its header and
/// its data (borrowed from the stream's buffer until the next call).
pub type StreamEntry<'a> = (&'a str, u64, &'a [u8]);

/// A streaming [`tar_entries`]: walks an untrusted archive from a reader, member after
/// member, holding one member's data at a time in a buffer that is reused. It refuses what
/// [`tar_entries`] refuses; a member whose header claims more than `max_member_bytes` is
/// refused by that header, before anything of it is read, so memory is bounded by the
/// limit, never by the file. The caller bounds the reader (a file's recorded size with
/// [`std::io::Read::take`]); `path` names the source in I/O errors.
///
/// ```
/// use bettimill_shard::{tar_bytes, Member, TarStream};
///
/// let shard = tar_bytes(&[
///     Member::new("s000000.cls", b"3"),
///     Member::new("s000000.json", br#"{"betti": [1, 1]}"#),
/// ])
/// .unwrap();
/// // A header and a padded data block per member, then the two-block end marker.
/// assert_eq!(shard.len(), 2 * (512 + 512) + 2 * 512);
///
/// let mut stream = TarStream::new(&shard[..], "s.tar", 1 << 20);
/// let mut members = Vec::new();
/// while let Some((name, header_offset, data)) = stream.next_entry().unwrap() {
///     members.push((name.to_string(), header_offset, data.to_vec()));
/// }
/// assert_eq!(members[0], ("s000000.cls".to_string(), 0, b"3".to_vec()));
/// assert_eq!(members[1].1, 1024);
/// assert_eq!(members[1].2, br#"{"betti": [1, 1]}"#);
///
/// // A member over the limit is refused by its header, before its data is read.
/// let mut small = TarStream::new(&shard[..], "s.tar", 8);
/// assert!(small.next_entry().is_ok());
/// assert!(small.next_entry().is_err());
/// ```
pub struct TarStream<R> {
    reader: R,
    path: std::path::PathBuf,
    max_member_bytes: u64,
    position: u64,
    data: Vec<u8>,
    name: String,
    header_offset: u64,
    done: bool,
}

impl<R: std::io::Read> TarStream<R> {
    /// A stream over `reader` (read from its current position as byte 0 of the archive).
    pub fn new(reader: R, path: impl Into<std::path::PathBuf>, max_member_bytes: u64) -> Self {
        TarStream {
            reader,
            path: path.into(),
            max_member_bytes,
            position: 0,
            data: Vec::new(),
            name: String::new(),
            header_offset: 0,
            done: false,
        }
    }

    /// Reads up to `buf.len()` bytes, fewer only at the end of the input.
    fn fill(&mut self, buf: &mut [u8]) -> Result<usize, ShardError> {
        let mut got = 0;
        while got < buf.len() {
            match self.reader.read(&mut buf[got..]) {
                Ok(0) => break,
                Ok(n) => got += n,
                Err(err) if err.kind() == std::io::ErrorKind::Interrupted => {}
                Err(err) => return Err(ShardError::io("cannot read", &self.path, err)),
            }
        }
        self.position += got as u64;
        Ok(got)
    }

    /// Reads one block; `Err` names what was being read if the input ends first.
    fn block(&mut self, context: impl FnOnce(u64) -> String) -> Result<[u8; 512], ShardError> {
        let start = self.position;
        let mut block = [0u8; 512];
        let got = self.fill(&mut block)?;
        if got < block.len() {
            return Err(ShardError::TarTruncated {
                offset: self.position,
                needed: BLOCK - got as u64,
                context: context(start),
            });
        }
        Ok(block)
    }

    /// The next regular-file member as (name, header offset, data), or `None` after the
    /// end-of-archive marker (and nothing but zeros after it).
    pub fn next_entry(&mut self) -> Result<Option<StreamEntry<'_>>, ShardError> {
        if self.done {
            return Ok(None);
        }
        loop {
            let pos = self.position;
            let mut first = [0u8; 1];
            if self.fill(&mut first)? == 0 {
                return Err(ShardError::TarTruncated {
                    offset: pos,
                    needed: 2 * BLOCK,
                    context: "the end-of-archive marker (two zero blocks) is missing".into(),
                });
            }
            let mut header = [0u8; 512];
            header[0] = first[0];
            let got = self.fill(&mut header[1..])?;
            if got < 511 {
                return Err(ShardError::TarTruncated {
                    offset: self.position,
                    needed: 511 - got as u64,
                    context: format!("header block at byte {pos}"),
                });
            }
            if header.iter().all(|&b| b == 0) {
                let second =
                    self.block(|at| format!("second end-of-archive block at byte {at}"))?;
                if let Some(i) = second.iter().position(|&b| b != 0) {
                    return Err(ShardError::Tar {
                        offset: pos + BLOCK + i as u64,
                        reason: "non-zero byte after the end-of-archive marker".into(),
                    });
                }
                let mut rest = [0u8; 8192];
                loop {
                    let start = self.position;
                    let got = self.fill(&mut rest)?;
                    if let Some(i) = rest[..got].iter().position(|&b| b != 0) {
                        return Err(ShardError::Tar {
                            offset: start + i as u64,
                            reason: "non-zero byte after the end-of-archive marker".into(),
                        });
                    }
                    if got < rest.len() {
                        break;
                    }
                }
                self.done = true;
                return Ok(None);
            }
            let entry = parse_header(&header, pos)?;
            if entry.size > self.max_member_bytes {
                return Err(ShardError::MemberTooLarge {
                    name: entry.name,
                    bytes: entry.size,
                    limit: self.max_member_bytes,
                });
            }
            // Grows with the bytes that arrive, not with the header's claim.
            let size = entry.size as usize;
            self.data.clear();
            let got = std::io::Read::read_to_end(
                &mut std::io::Read::take(&mut self.reader, entry.size),
                &mut self.data,
            )
            .map_err(|err| ShardError::io("cannot read", &self.path, err))?;
            self.position += got as u64;
            if got < size {
                return Err(ShardError::TarTruncated {
                    offset: self.position,
                    needed: (size - got) as u64,
                    context: format!("data of {:?} (header at byte {pos})", entry.name),
                });
            }
            let padding = (round_up(entry.size) - entry.size) as usize;
            let mut pad = [0u8; 512];
            let got = self.fill(&mut pad[..padding])?;
            if got < padding {
                return Err(ShardError::TarTruncated {
                    offset: self.position,
                    needed: (padding - got) as u64,
                    context: format!("padding after {:?}", entry.name),
                });
            }
            if let EntryKind::File = entry.kind {
                self.name = entry.name;
                self.header_offset = pos;
                return Ok(Some((&self.name, self.header_offset, &self.data)));
            }
        }
    }
}

enum EntryKind {
    File,
    Directory,
}

struct Header {
    name: String,
    size: u64,
    kind: EntryKind,
}

fn parse_header(header: &[u8], offset: u64) -> Result<Header, ShardError> {
    let stored = parse_octal(&header[148..156], offset + 148, "checksum")?;
    let unsigned: u64 = header
        .iter()
        .enumerate()
        .map(|(i, &b)| {
            if (148..156).contains(&i) {
                32
            } else {
                b as u64
            }
        })
        .sum();
    let signed: i64 = header
        .iter()
        .enumerate()
        .map(|(i, &b)| {
            if (148..156).contains(&i) {
                32
            } else {
                b as i8 as i64
            }
        })
        .sum();
    if stored != unsigned && stored as i64 != signed {
        return Err(ShardError::HeaderChecksum {
            offset,
            expected: stored,
            found: unsigned,
        });
    }
    let magic = &header[257..265];
    let is_ustar = magic == b"ustar\x0000" || magic == b"ustar  \0";
    if !is_ustar {
        return Err(ShardError::Tar {
            offset: offset + 257,
            reason: format!(
                "magic {:?} is neither POSIX nor GNU ustar",
                String::from_utf8_lossy(magic)
            ),
        });
    }
    let raw_name = c_string(&header[..100]);
    let prefix = if magic == b"ustar\x0000" {
        c_string(&header[345..500])
    } else {
        &[]
    };
    let mut full = Vec::with_capacity(prefix.len() + 1 + raw_name.len());
    if !prefix.is_empty() {
        full.extend_from_slice(prefix);
        full.push(b'/');
    }
    full.extend_from_slice(raw_name);
    let name = String::from_utf8(full).map_err(|e| ShardError::Tar {
        offset,
        reason: format!(
            "member name {:?} is not UTF-8",
            String::from_utf8_lossy(e.as_bytes())
        ),
    })?;
    let size = parse_octal(&header[124..136], offset + 124, "size")?;
    let typeflag = header[156] as char;
    let unsupported = |kind| ShardError::UnsupportedEntry {
        name: name.clone(),
        offset,
        typeflag,
        kind,
    };
    let kind = match typeflag {
        '0' | '\0' | '7' => EntryKind::File,
        '5' => EntryKind::Directory,
        '1' => return Err(unsupported("hard link")),
        '2' => return Err(unsupported("symbolic link")),
        '3' => return Err(unsupported("character device")),
        '4' => return Err(unsupported("block device")),
        '6' => return Err(unsupported("FIFO")),
        'x' | 'g' => return Err(unsupported("PAX extended header")),
        'L' | 'K' => return Err(unsupported("GNU long name")),
        _ => return Err(unsupported("unknown type")),
    };
    match kind {
        EntryKind::Directory => {
            check_safe_path(name.trim_end_matches('/'))?;
        }
        EntryKind::File => check_safe_path(&name)?,
    }
    Ok(Header { name, size, kind })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn members(names: &[&str]) -> Vec<Member> {
        names
            .iter()
            .enumerate()
            .map(|(i, name)| Member::new(*name, vec![i as u8 + 1; 100 * i + 3]))
            .collect()
    }

    #[test]
    fn layout_matches_the_documented_offsets() {
        let ms = members(&["a/s1.npy", "a/s1.json"]);
        let bytes = tar_bytes(&ms).unwrap();
        assert_eq!(bytes.len() as u64, tar_len([3, 103]));
        assert_eq!(bytes.len(), 512 + 512 + 512 + 512 + 1024);
        assert_eq!(&bytes[..8], b"a/s1.npy");
        assert_eq!(&bytes[100..108], b"0000444\0");
        assert_eq!(&bytes[124..136], b"00000000003\0");
        assert_eq!(&bytes[136..148], b"00000000000\0");
        assert_eq!(&bytes[257..265], b"ustar\x0000");
        assert_eq!(&bytes[265..275], b"bettimill\0");
        assert_eq!(&bytes[512..515], &[1, 1, 1]);
        assert!(bytes[515..1024].iter().all(|&b| b == 0));
        assert_eq!(&bytes[1024..1033], b"a/s1.json");
        assert!(bytes[bytes.len() - 1024..].iter().all(|&b| b == 0));
    }

    #[test]
    fn names_are_checked() {
        let cases: &[(&str, bool)] = &[
            ("train/s000001.npy", true),
            ("s000001.npy.gz", true),
            ("a-b_c/d.e.f", true),
            ("/abs.npy", false),
            ("../up.npy", false),
            ("a/../b.npy", false),
            ("a//b.npy", false),
            ("./a.npy", false),
            ("noext", false),
            (".npy", false),
            ("a.b/c.npy", false),
            ("a/b.npy.", false),
            ("a/b..npy", false),
            ("sp ace.npy", false),
            ("__key__.json", false),
            ("dir/", false),
            ("", false),
        ];
        for &(name, ok) in cases {
            assert_eq!(check_member_name(name).is_ok(), ok, "{name}");
        }
        let long = format!("{}.npy", "k".repeat(97));
        assert_eq!(long.len(), 101);
        assert!(check_member_name(&long).is_err());
        assert!(check_member_name(&long[1..]).is_ok());
    }

    #[test]
    fn split_key_uses_the_first_dot_of_the_last_component() {
        assert_eq!(split_key("train/s1.npy.gz"), Some(("train/s1", "npy.gz")));
        assert_eq!(split_key("s1.json"), Some(("s1", "json")));
        assert_eq!(split_key("dir/noext"), None);
    }

    /// Every entry of a stream, owned.
    fn streamed(bytes: &[u8], limit: u64) -> Result<Vec<(String, u64, Vec<u8>)>, ShardError> {
        let mut stream = TarStream::new(bytes, "t.tar", limit);
        let mut found = Vec::new();
        while let Some((name, offset, data)) = stream.next_entry()? {
            found.push((name.to_string(), offset, data.to_vec()));
        }
        Ok(found)
    }

    #[test]
    fn the_stream_reads_what_tar_entries_reads_and_refuses_what_it_refuses() {
        let bytes = tar_bytes(&members(&["a.json", "a.npy", "b.json"])).unwrap();
        let entries: Vec<_> = tar_entries(&bytes, u64::MAX)
            .unwrap()
            .into_iter()
            .map(|e| (e.name, e.header_offset, e.data.to_vec()))
            .collect();
        assert_eq!(streamed(&bytes, u64::MAX).unwrap(), entries);
        for cut in [0, 100, 512, 700, bytes.len() - 512, bytes.len() - 1] {
            assert!(matches!(
                streamed(&bytes[..cut], u64::MAX),
                Err(ShardError::TarTruncated { .. })
            ));
        }
        let mut garbage = bytes.clone();
        garbage.extend_from_slice(&[0, 0, 9]);
        assert!(matches!(
            streamed(&garbage, u64::MAX),
            Err(ShardError::Tar { offset, .. }) if offset == bytes.len() as u64 + 2
        ));
        // A member over the limit is refused by its header: the limit is the largest
        // member here (203 bytes), one byte less refuses it.
        assert_eq!(streamed(&bytes, 203).unwrap().len(), 3);
        assert!(matches!(
            streamed(&bytes, 202),
            Err(ShardError::MemberTooLarge {
                bytes: 203,
                limit: 202,
                ..
            })
        ));
        // A header claiming a huge member on a short input allocates nothing for it.
        let mut huge = header_block("big.npy", (1 << 33) - 1).unwrap().to_vec();
        huge.extend_from_slice(&[1; 10]);
        assert!(matches!(
            streamed(&huge, u64::MAX),
            Err(ShardError::TarTruncated { .. })
        ));
    }

    #[test]
    fn missing_end_marker_and_trailing_garbage_are_errors() {
        let bytes = tar_bytes(&members(&["s1.npy"])).unwrap();
        let no_marker = &bytes[..bytes.len() - 1024];
        assert!(matches!(
            read_tar(no_marker),
            Err(ShardError::TarTruncated { needed: 1024, .. })
        ));
        let half_marker = &bytes[..bytes.len() - 512];
        assert!(matches!(
            read_tar(half_marker),
            Err(ShardError::TarTruncated { needed: 512, .. })
        ));
        let mut garbage = bytes.clone();
        garbage.extend_from_slice(&[0, 0, 9]);
        assert!(matches!(
            read_tar(&garbage),
            Err(ShardError::Tar { offset, .. }) if offset == bytes.len() as u64 + 2
        ));
        let mut zeros = bytes.clone();
        zeros.extend_from_slice(&[0; 9216]);
        assert_eq!(read_tar(&zeros).unwrap().len(), 1);
    }
}
