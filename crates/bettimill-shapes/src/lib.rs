//! bettimill-shapes (being written).
