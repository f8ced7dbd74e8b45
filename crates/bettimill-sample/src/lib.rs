//! bettimill-sample (being written).
