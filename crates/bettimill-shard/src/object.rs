//! Objects under an `s3://BUCKET/PREFIX` URL, through Apache Arrow's `object_store` (its
//! S3 client: signing, retries, conditional and multipart puts), behind a blocking facade
//! so that the rest of bettimill stays synchronous.
//!
//! The guarantees of [`crate::atomic`] carry over: an object appears whole or not at all
//! (a single put, or a completed multipart upload), and every write here is create-only,
//! so two writers never overwrite each other: the second is told the object exists
//! ([`ObjectError::Exists`]) and compares instead.
//!
//! A file larger than one part ([`ObjectDir::put_file_new`]) is streamed, never held in
//! memory whole: S3 has no create-only completion of a multipart upload in `object_store`'s
//! API, so the file goes by a multipart upload to a temporary object of its own (under
//! [`UPLOADS_DIR`], named by the writer), which is then copied to its name create-only
//! (`object_store`'s copy-if-not-exists: a server-side multipart copy completed with
//! `If-None-Match: *`) and deleted. A writer killed in between leaves a temporary object
//! (removed by the next finalize) or an unfinished multipart upload (invisible; a bucket
//! lifecycle rule that aborts unfinished uploads removes its parts), never a partial
//! object under a real name.
//!
//! Nothing here reads the environment: the caller passes the endpoint and credentials
//! ([`S3Config`]), read where every variable is read.

use futures_util::TryStreamExt;
use object_store::aws::{AmazonS3, AmazonS3Builder, S3CopyIfNotExists};
use object_store::path::Path as ObjectPath;
use object_store::{
    ClientOptions, ObjectStore, ObjectStoreExt, PutMode, PutOptions, PutPayload, RetryConfig,
    WriteMultipart,
};
use std::io::Read;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The scheme of an object-storage URL.
pub const S3_SCHEME: &str = "s3://";

/// Whether `location` names object storage (`s3://...`) rather than a local path.
pub fn is_object_url(location: &str) -> bool {
    location.starts_with(S3_SCHEME)
}

/// Where and as whom to reach an S3-compatible server. Every field is optional: unset, the
/// server is AWS S3 in `us-east-1` and requests are signed with no key (which AWS refuses).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct S3Config {
    /// The server's base URL (`http://127.0.0.1:9000`, `https://ACCOUNT.r2.cloudflarestorage.com`);
    /// plain `http://` is allowed only when given here.
    pub endpoint: Option<String>,
    /// The access key id.
    pub access_key_id: Option<String>,
    /// The secret access key.
    pub secret_access_key: Option<String>,
    /// A session token, for temporary credentials.
    pub session_token: Option<String>,
    /// The region (default `us-east-1`).
    pub region: Option<String>,
}

/// A failure to reach or use object storage; every variant names the URL.
#[derive(Debug, thiserror::Error)]
pub enum ObjectError {
    /// The URL is not `s3://BUCKET/PREFIX`.
    #[error("{url}: not an object-storage URL: {reason}")]
    BadUrl {
        /// The URL as given.
        url: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The bucket does not exist.
    #[error("{url}: the bucket {bucket} does not exist at {endpoint}")]
    NoBucket {
        /// The URL.
        url: String,
        /// The bucket.
        bucket: String,
        /// The server.
        endpoint: String,
    },
    /// The server refused the credentials or the request's signature.
    #[error(
        "{url}: the server refused the credentials (check AWS_ACCESS_KEY_ID and \
         AWS_SECRET_ACCESS_KEY): {reason}"
    )]
    Denied {
        /// The URL.
        url: String,
        /// The server's answer.
        reason: String,
    },
    /// The object exists already: a create-only put found another writer's object.
    #[error("{url}: the object exists already (objects are never overwritten)")]
    Exists {
        /// The object's URL.
        url: String,
    },
    /// A local file to upload cannot be read.
    #[error("{}: {source}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The object does not exist.
    #[error("{url}: no such object")]
    NotFound {
        /// The object's URL.
        url: String,
    },
    /// Anything else: the server cannot be reached, or answered with an error.
    #[error("{url}: {reason}")]
    Failed {
        /// The URL.
        url: String,
        /// What went wrong.
        reason: String,
    },
}

/// An object's name and size in a listing.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ObjectEntry {
    /// The name relative to the prefix (`shards/NAME-000000.tar`).
    pub name: String,
    /// Its size in bytes.
    pub bytes: u64,
}

/// The objects under one `s3://BUCKET/PREFIX`, named relative to the prefix with `/`
/// between parts, as files are named relative to a dataset directory.
pub struct ObjectDir {
    store: AmazonS3,
    runtime: tokio::runtime::Runtime,
    url: String,
    bucket: String,
    prefix: String,
    endpoint: String,
}

impl std::fmt::Debug for ObjectDir {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ObjectDir").field("url", &self.url).finish()
    }
}

/// `s3://BUCKET/PREFIX` split into the bucket and the prefix (without slashes at its ends;
/// empty for the bucket's root).
pub fn parse_s3_url(url: &str) -> Result<(String, String), ObjectError> {
    let bad = |reason: &str| ObjectError::BadUrl {
        url: url.to_string(),
        reason: reason.to_string(),
    };
    let rest = url
        .strip_prefix(S3_SCHEME)
        .ok_or_else(|| bad("it does not start with s3://"))?;
    let (bucket, prefix) = rest.split_once('/').unwrap_or((rest, ""));
    let valid_bucket = (3..=63).contains(&bucket.len())
        && bucket
            .bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-' || b == b'.');
    if !valid_bucket {
        return Err(bad(
            "the bucket name is 3-63 lower-case letters, digits, '-' and '.'",
        ));
    }
    let prefix = prefix.trim_matches('/');
    if prefix.split('/').any(|part| part == "." || part == "..") || prefix.contains("//") {
        return Err(bad("the prefix has an empty, '.' or '..' part"));
    }
    Ok((bucket.to_string(), prefix.to_string()))
}

impl ObjectDir {
    /// Connects to `url` (`s3://BUCKET/PREFIX`) and checks, with one listing request, that
    /// the server answers, accepts the credentials and has the bucket: a wrong key, a
    /// missing bucket or an unreachable server is an error here, before any work.
    pub fn open(url: &str, config: &S3Config) -> Result<ObjectDir, ObjectError> {
        let (bucket, prefix) = parse_s3_url(url)?;
        let failed = |reason: String| ObjectError::Failed {
            url: url.to_string(),
            reason,
        };
        let region = config.region.clone().unwrap_or_else(|| "us-east-1".into());
        let mut builder = AmazonS3Builder::new()
            .with_bucket_name(&bucket)
            .with_region(&region)
            // The create-only copy that gives a streamed upload its name (see the module
            // documentation): a multipart copy completed with `If-None-Match: *`.
            .with_copy_if_not_exists(S3CopyIfNotExists::Multipart)
            // A few quick retries: an unreachable server is reported in seconds, not after
            // the client's default three minutes.
            .with_retry(RetryConfig {
                max_retries: 3,
                retry_timeout: Duration::from_secs(30),
                ..RetryConfig::default()
            })
            .with_client_options(
                ClientOptions::new()
                    .with_connect_timeout(Duration::from_secs(5))
                    .with_timeout(Duration::from_secs(300)),
            );
        let endpoint = match &config.endpoint {
            Some(endpoint) => {
                builder = builder
                    .with_endpoint(endpoint)
                    .with_allow_http(endpoint.starts_with("http://"));
                endpoint.clone()
            }
            None => format!("https://s3.{region}.amazonaws.com"),
        };
        if let Some(key) = &config.access_key_id {
            builder = builder.with_access_key_id(key);
        }
        if let Some(secret) = &config.secret_access_key {
            builder = builder.with_secret_access_key(secret);
        }
        if let Some(token) = &config.session_token {
            builder = builder.with_token(token);
        }
        // rustls needs one process-wide crypto provider; a second install is refused and
        // harmless. ring's is marked deprecated for lacking post-quantum key exchange; it
        // keeps the aws-lc C library (a long build) out of the tree, and X25519 with
        // TLS 1.3 is what S3 endpoints negotiate today.
        #[allow(deprecated)]
        let provider = rustls::crypto::ring::default_provider();
        let _ = provider.install_default();
        let store = builder.build().map_err(|err| failed(err.to_string()))?;
        // Two I/O threads drive every connection; any thread may block on a request, so a
        // writer can upload several objects at once from threads of its own.
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("bettimill-object-io")
            .enable_all()
            .build()
            .map_err(|err| failed(format!("cannot start the I/O runtime: {err}")))?;
        let dir = ObjectDir {
            store,
            runtime,
            url: url.to_string(),
            bucket,
            prefix,
            endpoint,
        };
        let root = dir.path("");
        dir.runtime
            .block_on(dir.store.list_with_delimiter(Some(&root)))
            .map_err(|err| dir.error(url, err))?;
        Ok(dir)
    }

    /// The URL this names.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// The URL of the object `name`.
    pub fn object_url(&self, name: &str) -> String {
        format!("{}/{name}", self.url.trim_end_matches('/'))
    }

    fn path(&self, name: &str) -> ObjectPath {
        match (self.prefix.is_empty(), name.is_empty()) {
            (true, _) => ObjectPath::from(name),
            (false, true) => ObjectPath::from(self.prefix.as_str()),
            (false, false) => ObjectPath::from(format!("{}/{name}", self.prefix)),
        }
    }

    /// Classifies a client error at `url`, in one line: the server's error code and
    /// message when it sent one, instead of its XML.
    fn error(&self, url: &str, err: object_store::Error) -> ObjectError {
        let url = url.to_string();
        let raw = err.to_string();
        let tag = |name: &str| {
            let open = format!("<{name}>");
            let start = raw.find(&open)? + open.len();
            let end = raw[start..].find(&format!("</{name}>"))? + start;
            Some(raw[start..end].to_string())
        };
        let text = match (tag("Code"), tag("Message")) {
            (Some(code), Some(message)) => format!("{code}: {message}"),
            (Some(code), None) => code,
            _ => raw.split_whitespace().collect::<Vec<_>>().join(" "),
        };
        const DENIED: [&str; 4] = [
            "SignatureDoesNotMatch",
            "InvalidAccessKeyId",
            "AccessDenied",
            "InvalidToken",
        ];
        if DENIED.iter().any(|code| text.starts_with(code)) {
            return ObjectError::Denied { url, reason: text };
        }
        match err {
            object_store::Error::AlreadyExists { .. }
            | object_store::Error::Precondition { .. } => ObjectError::Exists { url },
            _ if text.starts_with("NoSuchBucket") || raw.contains("NoSuchBucket") => {
                ObjectError::NoBucket {
                    url,
                    bucket: self.bucket.clone(),
                    endpoint: self.endpoint.clone(),
                }
            }
            object_store::Error::NotFound { .. } => ObjectError::NotFound { url },
            object_store::Error::PermissionDenied { .. }
            | object_store::Error::Unauthenticated { .. } => {
                ObjectError::Denied { url, reason: text }
            }
            // No answer at all (refused, timed out, no route): the client's text is a
            // request line with timings; the server and the last cause say it all.
            _ if text.contains("error sending request") => ObjectError::Failed {
                url,
                reason: format!(
                    "cannot reach the server {} (no answer after retries; check --endpoint or \
                     AWS_ENDPOINT_URL, and the network)",
                    self.endpoint
                ),
            },
            _ => ObjectError::Failed { url, reason: text },
        }
    }

    /// Writes `bytes` as the object `name` in one put, create-only: an existing object is
    /// left as it is and reported as [`ObjectError::Exists`].
    pub fn put_new(&self, name: &str, bytes: Vec<u8>) -> Result<(), ObjectError> {
        let options = PutOptions {
            mode: PutMode::Create,
            ..PutOptions::default()
        };
        self.runtime
            .block_on(
                self.store
                    .put_opts(&self.path(name), PutPayload::from(bytes), options),
            )
            .map(|_| ())
            .map_err(|err| self.error(&self.object_url(name), err))
    }

    /// Writes the file `file` as the object `name`, create-only, holding at most
    /// [`PARTS_IN_FLIGHT`] parts of it in memory whatever its size: a file of at most
    /// one part in one put ([`ObjectDir::put_new`]), a larger one streamed by a multipart
    /// upload to a temporary object under [`UPLOADS_DIR`], then copied to `name` by the
    /// server, create-only, and the temporary deleted (see the module documentation). An
    /// existing object is left as it is and reported as [`ObjectError::Exists`].
    pub fn put_file_new(&self, name: &str, file: &Path) -> Result<(), ObjectError> {
        let io = |source| ObjectError::File {
            path: file.to_path_buf(),
            source,
        };
        let mut reader = std::fs::File::open(file).map_err(io)?;
        let size = reader.metadata().map_err(io)?.len();
        if size <= PART_BYTES as u64 {
            let mut bytes = Vec::with_capacity(size as usize);
            reader.read_to_end(&mut bytes).map_err(io)?;
            return self.put_new(name, bytes);
        }
        // An object there already (a resumed build's, or another writer's) is found with
        // one request rather than after uploading the whole file.
        if self.size(name)?.is_some() {
            return Err(ObjectError::Exists {
                url: self.object_url(name),
            });
        }
        self.stream_to(name, file, &mut reader, size)
    }

    /// The streamed path of [`ObjectDir::put_file_new`] for a file of any size, without its
    /// early check for an existing object: a multipart upload to a temporary object, a
    /// create-only copy to `name` by the server ([`ObjectError::Exists`] when `name`
    /// exists by then), and the temporary's deletion.
    pub fn put_file_streamed(&self, name: &str, file: &Path) -> Result<(), ObjectError> {
        let io = |source| ObjectError::File {
            path: file.to_path_buf(),
            source,
        };
        let mut reader = std::fs::File::open(file).map_err(io)?;
        let size = reader.metadata().map_err(io)?.len();
        self.stream_to(name, file, &mut reader, size)
    }

    /// [`ObjectDir::put_file_streamed`] from the open file `reader` of `size` bytes.
    fn stream_to(
        &self,
        name: &str,
        file: &Path,
        reader: &mut std::fs::File,
        size: u64,
    ) -> Result<(), ObjectError> {
        if size > MAX_STREAMED_OBJECT_BYTES {
            return Err(ObjectError::Failed {
                url: self.object_url(name),
                reason: format!(
                    "{} is {size} bytes; an object written create-only by a streamed upload \
                     holds at most {MAX_STREAMED_OBJECT_BYTES} bytes (5 GiB, S3's largest \
                     server-side copy)",
                    file.display()
                ),
            });
        }
        let temporary = temporary_name(name);
        let uploaded = self.upload_parts(&temporary, reader, size, file);
        let copied = uploaded.and_then(|()| {
            self.runtime
                .block_on(
                    self.store
                        .copy_if_not_exists(&self.path(&temporary), &self.path(name)),
                )
                .map_err(|err| self.error(&self.object_url(name), err))
        });
        // Best effort: a temporary left here is removed by the next finalize.
        let _ = self.delete(&temporary);
        copied
    }

    /// Uploads `size` bytes of `reader` (the file `file`) as the object `name` by a
    /// multipart upload of parts of [`part_bytes`], at most [`PARTS_IN_FLIGHT`] held at once
    /// (in flight, or being read);
    /// the upload is aborted when anything fails.
    fn upload_parts(
        &self,
        name: &str,
        reader: &mut std::fs::File,
        size: u64,
        file: &Path,
    ) -> Result<(), ObjectError> {
        let url = self.object_url(name);
        let part = part_bytes(size);
        self.runtime.block_on(async {
            let upload = self
                .store
                .put_multipart(&self.path(name))
                .await
                .map_err(|err| self.error(&url, err))?;
            let mut writer = WriteMultipart::new_with_chunk_size(upload, part);
            let mut sent = 0u64;
            let failure = loop {
                // Each part is read into a buffer of its own and handed over without a copy;
                // fewer than PARTS_IN_FLIGHT are in flight while the next one is read.
                if let Err(err) = writer.wait_for_capacity(PARTS_IN_FLIGHT).await {
                    break self.error(&url, err);
                }
                let mut buffer = Vec::with_capacity(part.max(PART_CAPACITY));
                buffer.resize(part.min((size - sent.min(size)) as usize), 0);
                let read = match read_full(reader, &mut buffer) {
                    Ok(read) => read,
                    Err(source) => {
                        break ObjectError::File {
                            path: file.to_path_buf(),
                            source,
                        }
                    }
                };
                if read == 0 {
                    if sent != size || reader.read(&mut [0u8; 1]).map_or(true, |n| n != 0) {
                        break ObjectError::File {
                            path: file.to_path_buf(),
                            source: std::io::Error::new(
                                std::io::ErrorKind::UnexpectedEof,
                                format!("changed while uploaded: not {size} bytes"),
                            ),
                        };
                    }
                    return writer
                        .finish()
                        .await
                        .map(|_| ())
                        .map_err(|err| self.error(&url, err));
                }
                buffer.truncate(read);
                writer.put(bytes::Bytes::from(buffer));
                sent += read as u64;
            };
            let _ = writer.abort().await;
            Err(failure)
        })
    }

    /// The whole object `name`, or `None` when it does not exist.
    pub fn get(&self, name: &str) -> Result<Option<Vec<u8>>, ObjectError> {
        let path = self.path(name);
        let result = self.runtime.block_on(async {
            let got = self.store.get(&path).await?;
            got.bytes().await
        });
        match result {
            Ok(bytes) => Ok(Some(bytes.to_vec())),
            Err(object_store::Error::NotFound { .. }) => Ok(None),
            Err(err) => Err(self.error(&self.object_url(name), err)),
        }
    }

    /// The bytes `range` of the object `name` (one ranged request).
    pub fn get_range(&self, name: &str, range: Range<u64>) -> Result<Vec<u8>, ObjectError> {
        self.runtime
            .block_on(self.store.get_range(&self.path(name), range))
            .map(|bytes| bytes.to_vec())
            .map_err(|err| self.error(&self.object_url(name), err))
    }

    /// The size of the object `name`, or `None` when it does not exist.
    pub fn size(&self, name: &str) -> Result<Option<u64>, ObjectError> {
        match self.runtime.block_on(self.store.head(&self.path(name))) {
            Ok(meta) => Ok(Some(meta.size)),
            Err(object_store::Error::NotFound { .. }) => Ok(None),
            Err(err) => Err(self.error(&self.object_url(name), err)),
        }
    }

    /// Deletes the object `name` (a missing object is no error).
    pub fn delete(&self, name: &str) -> Result<(), ObjectError> {
        match self.runtime.block_on(self.store.delete(&self.path(name))) {
            Ok(()) | Err(object_store::Error::NotFound { .. }) => Ok(()),
            Err(err) => Err(self.error(&self.object_url(name), err)),
        }
    }

    /// Every object under the prefix, sorted by name.
    pub fn list(&self) -> Result<Vec<ObjectEntry>, ObjectError> {
        self.list_under("")
    }

    /// Every object under `PREFIX/under/` (`under` empty: the whole prefix), sorted by name
    /// and named relative to the prefix.
    pub fn list_under(&self, under: &str) -> Result<Vec<ObjectEntry>, ObjectError> {
        let root = self.path(under);
        let skip = if self.prefix.is_empty() {
            0
        } else {
            self.prefix.len() + 1
        };
        let mut entries: Vec<ObjectEntry> = self
            .runtime
            .block_on(self.store.list(Some(&root)).try_collect::<Vec<_>>())
            .map_err(|err| self.error(&self.url, err))?
            .into_iter()
            .map(|meta| ObjectEntry {
                name: meta.location.as_ref()[skip..].to_string(),
                bytes: meta.size,
            })
            .collect();
        entries.sort_by(|a, b| a.name.cmp(&b.name));
        Ok(entries)
    }
}

/// The parts of a streamed upload ([`ObjectDir::put_file_new`]): files up to this size go
/// in one put. Above S3's minimum part (5 MiB); small enough that a few uploads at once
/// hold little memory.
pub const PART_BYTES: usize = 8 << 20;

/// The capacity of a part's buffer, of which only the part's bytes are ever touched (so
/// resident): above glibc's largest dynamic mmap threshold (32 MiB), so that freeing a part
/// does not raise the threshold for the rest of the process. Raised to 8 MiB, it would put
/// the samples' buffers below that size on the heap, where they fragment: a build of 48 MiB
/// shards peaked 15 MiB higher.
const PART_CAPACITY: usize = 33 << 20;

/// Parts of one streamed upload held in memory at once: those in flight and the one being
/// read (two: the next part is read while one is sent).
pub const PARTS_IN_FLIGHT: usize = 2;

/// S3's largest number of parts in a multipart upload.
const MAX_PARTS: u64 = 10_000;

/// The largest object a streamed upload can name: its create-only copy to the real name is
/// one `UploadPartCopy` of the whole temporary object, which S3 caps at 5 GiB (the copy of
/// `object_store`, the only create-only completion it offers for a multipart upload, is a
/// single part). Plans that could make a larger shard are refused for object storage before
/// any work.
pub const MAX_STREAMED_OBJECT_BYTES: u64 = 5 << 30;

/// The directory, under the prefix, of the temporary objects of streamed uploads. Its name
/// starts with a dot: readers and copies skip it, as they skip a directory's temporaries.
pub const UPLOADS_DIR: &str = ".uploads";

/// The part size for a file of `size` bytes: [`PART_BYTES`], or larger (whole MiB) when
/// the file needs more than S3's 10 000 parts of it.
pub fn part_bytes(size: u64) -> usize {
    let least = size.div_ceil(MAX_PARTS).next_multiple_of(1 << 20);
    least.max(PART_BYTES as u64) as usize
}

/// A temporary object's name for a streamed upload of `name`: unique to this writer (its
/// process, the time, a counter), so that two writers never share one.
fn temporary_name(name: &str) -> String {
    static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let count = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    format!(
        "{UPLOADS_DIR}/{name}.{}-{nanos}-{count}",
        std::process::id()
    )
}

/// Reads until `buffer` is full or the file ends; returns the bytes read.
fn read_full(reader: &mut impl Read, buffer: &mut [u8]) -> std::io::Result<usize> {
    let mut filled = 0;
    while filled < buffer.len() {
        match reader.read(&mut buffer[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(err) if err.kind() == std::io::ErrorKind::Interrupted => {}
            Err(err) => return Err(err),
        }
    }
    Ok(filled)
}

/// A reader of one object that fetches it by ranges of at most [`RANGE_BYTES`]: memory stays
/// at one range whatever the object's size.
pub struct RangeReader<'a> {
    dir: &'a ObjectDir,
    name: String,
    size: u64,
    at: u64,
    buffer: Vec<u8>,
    used: usize,
}

/// The largest range a [`RangeReader`] fetches at once.
pub const RANGE_BYTES: u64 = 8 << 20;

impl ObjectDir {
    /// A reader of the object `name`, whose size is `size` (from a listing or
    /// [`ObjectDir::size`]): ranged requests of [`RANGE_BYTES`] at most, one at a time.
    pub fn reader(&self, name: &str, size: u64) -> RangeReader<'_> {
        RangeReader {
            dir: self,
            name: name.to_string(),
            size,
            at: 0,
            buffer: Vec::new(),
            used: 0,
        }
    }
}

impl std::io::Read for RangeReader<'_> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        if self.used == self.buffer.len() {
            if self.at >= self.size || out.is_empty() {
                return Ok(0);
            }
            let end = (self.at + RANGE_BYTES).min(self.size);
            self.buffer = self
                .dir
                .get_range(&self.name, self.at..end)
                .map_err(std::io::Error::other)?;
            if self.buffer.is_empty() {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::UnexpectedEof,
                    format!(
                        "{}: shorter than {} bytes",
                        self.dir.object_url(&self.name),
                        self.size
                    ),
                ));
            }
            self.at += self.buffer.len() as u64;
            self.used = 0;
        }
        let n = out.len().min(self.buffer.len() - self.used);
        out[..n].copy_from_slice(&self.buffer[self.used..self.used + n]);
        self.used += n;
        Ok(n)
    }
}
