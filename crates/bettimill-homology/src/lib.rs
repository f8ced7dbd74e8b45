//! bettimill-homology (being written).
