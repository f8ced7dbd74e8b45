//! bettimill-deform (being written).
