//! Object storage against a real local S3 server (moto_server, started by ci/s3-up.sh):
//! create-only puts (single and streamed), ranged reads, listings, and one clear error naming the URL for wrong
//! credentials, a missing bucket and an unreachable server, all at open, before any work.
//!
//! A system test: it runs only with BETTIMILL_SYSTEM_TESTS=1 (ci/test.sh sets it), because
//! it installs and starts the server (idempotent; a no-op when it is up). When the server
//! cannot be started it fails in CI (CI=true) and is skipped with a message elsewhere.

mod common;

use bettimill_shard::object::{ObjectDir, ObjectError, S3Config, PART_BYTES, UPLOADS_DIR};
use bettimill_testkit::system_test;
use common::s3_up;

#[test]
fn puts_are_create_only_and_reads_take_ranges() {
    if !system_test("object storage on a local S3 server") {
        return;
    }
    let Some((server, config)) = s3_up() else {
        return;
    };
    let url = format!(
        "s3://{}/{}",
        server.bucket,
        server.fresh_prefix("shard-tests", "puts")
    );
    let dir = ObjectDir::open(&url, &config).unwrap();
    assert_eq!(dir.list().unwrap(), vec![], "a fresh prefix is empty");
    assert_eq!(dir.get("shards/a.tar").unwrap(), None);
    assert_eq!(dir.size("shards/a.tar").unwrap(), None);

    let bytes: Vec<u8> = (0..=255u8).cycle().take(70_000).collect();
    dir.put_new("shards/a.tar", bytes.clone()).unwrap();
    dir.put_new("records/a.json", b"{}\n".to_vec()).unwrap();
    assert_eq!(
        dir.get("shards/a.tar").unwrap().as_deref(),
        Some(&bytes[..])
    );
    assert_eq!(dir.size("shards/a.tar").unwrap(), Some(70_000));
    assert_eq!(
        dir.get_range("shards/a.tar", 1000..1300).unwrap(),
        bytes[1000..1300]
    );

    // A second writer of the same name is refused, and the first one's bytes stay.
    let err = dir.put_new("shards/a.tar", vec![1, 2, 3]).unwrap_err();
    assert!(matches!(err, ObjectError::Exists { .. }), "{err:?}");
    assert!(
        err.to_string()
            .starts_with(&format!("{url}/shards/a.tar: the object exists already")),
        "{err}"
    );
    assert_eq!(
        dir.get("shards/a.tar").unwrap().as_deref(),
        Some(&bytes[..])
    );

    let listed: Vec<(String, u64)> = dir
        .list()
        .unwrap()
        .into_iter()
        .map(|e| (e.name, e.bytes))
        .collect();
    assert_eq!(
        listed,
        vec![
            ("records/a.json".to_string(), 3),
            ("shards/a.tar".to_string(), 70_000)
        ]
    );
    dir.delete("records/a.json").unwrap();
    assert_eq!(dir.size("records/a.json").unwrap(), None);
}

#[test]
fn wrong_credentials_a_missing_bucket_and_no_server_fail_at_open() {
    if !system_test("object storage on a local S3 server") {
        return;
    }
    let Some((server, config)) = s3_up() else {
        return;
    };
    let url = format!(
        "s3://{}/{}",
        server.bucket,
        server.fresh_prefix("shard-tests", "errors")
    );

    let wrong = S3Config {
        secret_access_key: Some("not-the-secret".into()),
        ..config.clone()
    };
    let err = ObjectDir::open(&url, &wrong).unwrap_err();
    assert!(matches!(err, ObjectError::Denied { .. }), "{err:?}");
    let text = err.to_string();
    assert!(
        text.starts_with(&format!("{url}: the server refused the credentials")),
        "{text}"
    );
    assert!(!text.contains('\n'), "one line: {text}");

    let missing = "s3://no-such-bucket-here/prefix";
    let err = ObjectDir::open(missing, &config).unwrap_err();
    assert!(matches!(err, ObjectError::NoBucket { .. }), "{err:?}");
    assert_eq!(
        err.to_string(),
        format!(
            "{missing}: the bucket no-such-bucket-here does not exist at {}",
            config.endpoint.as_deref().unwrap()
        )
    );

    // Nothing listens on port 9 (discard) of loopback.
    let nowhere = S3Config {
        endpoint: Some("http://127.0.0.1:9".into()),
        ..config
    };
    let err = ObjectDir::open(&url, &nowhere).unwrap_err();
    assert!(matches!(err, ObjectError::Failed { .. }), "{err:?}");
    assert!(
        err.to_string().starts_with(&format!(
            "{url}: cannot reach the server http://127.0.0.1:9 "
        )),
        "{err}"
    );
}

#[test]
fn urls_name_a_bucket_and_a_clean_prefix() {
    use bettimill_shard::object::parse_s3_url;
    assert_eq!(
        parse_s3_url("s3://bucket/a/b/").unwrap(),
        ("bucket".to_string(), "a/b".to_string())
    );
    assert_eq!(
        parse_s3_url("s3://bucket").unwrap(),
        ("bucket".to_string(), String::new())
    );
    for bad in [
        "/tmp/x",
        "s3://",
        "s3://Bucket/x",
        "s3://b/x",
        "s3://bucket/a/../b",
        "s3://bucket/a//b",
    ] {
        let err = parse_s3_url(bad).unwrap_err();
        assert!(
            err.to_string()
                .starts_with(&format!("{bad}: not an object-storage URL")),
            "{err}"
        );
    }
}

#[test]
fn streamed_uploads_are_create_only_and_leave_no_temporary() {
    if !system_test("object storage on a local S3 server") {
        return;
    }
    let Some((server, config)) = s3_up() else {
        return;
    };
    let url = format!(
        "s3://{}/{}",
        server.bucket,
        server.fresh_prefix("shard-tests", "streamed")
    );
    let dir = ObjectDir::open(&url, &config).unwrap();
    // Two files of three parts and a bit, different in every byte.
    let scratch = tempfile::tempdir().unwrap();
    let size = 3 * PART_BYTES + 1000;
    let file = |fill: u8| {
        let path = scratch.path().join(format!("{fill}.tar"));
        std::fs::write(&path, vec![fill; size]).unwrap();
        path
    };
    let (first, second) = (file(1), file(2));
    dir.put_file_new("shards/a.tar", &first).unwrap();
    assert!(dir.get("shards/a.tar").unwrap().unwrap() == vec![1u8; size]);
    // A second writer is refused at once, before uploading.
    let err = dir.put_file_new("shards/a.tar", &second).unwrap_err();
    assert!(matches!(err, ObjectError::Exists { .. }), "{err:?}");
    // One that found no object and uploaded meanwhile is refused by the create-only copy
    // that would give its upload the name.
    let err = dir.put_file_streamed("shards/a.tar", &second).unwrap_err();
    assert!(matches!(err, ObjectError::Exists { .. }), "{err:?}");
    assert!(
        dir.get("shards/a.tar").unwrap().unwrap() == vec![1u8; size],
        "the first writer's object stays, whole"
    );
    // A file of one part or less goes in one put, create-only as well.
    let small = scratch.path().join("small");
    std::fs::write(&small, b"small").unwrap();
    dir.put_file_new("records/a.json", &small).unwrap();
    assert!(matches!(
        dir.put_file_new("records/a.json", &small),
        Err(ObjectError::Exists { .. })
    ));
    let names: Vec<String> = dir.list().unwrap().into_iter().map(|e| e.name).collect();
    assert_eq!(
        names,
        ["records/a.json", "shards/a.tar"],
        "no {UPLOADS_DIR}/ left"
    );
}
