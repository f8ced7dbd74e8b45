//! bettimill-noise (being written).
