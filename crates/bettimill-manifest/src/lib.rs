//! bettimill-manifest (being written).
