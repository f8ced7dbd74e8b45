//! bettimill-executor (being written).
