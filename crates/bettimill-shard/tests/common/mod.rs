//! What the object-storage test binaries share.

use bettimill_shard::object::S3Config;
use bettimill_testkit::s3::S3Server;

/// The shared server's endpoint, credentials and bucket, after starting it; `None` (skip)
/// only outside CI.
pub fn s3_up() -> Option<(S3Server, S3Config)> {
    let server = S3Server::shared()?;
    let config = S3Config {
        endpoint: Some(server.endpoint.clone()),
        access_key_id: Some(server.access_key_id.clone()),
        secret_access_key: Some(server.secret_access_key.clone()),
        session_token: None,
        region: Some(server.region.clone()),
    };
    Some((server, config))
}
