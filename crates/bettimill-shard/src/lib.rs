//! bettimill-shard (being written).
