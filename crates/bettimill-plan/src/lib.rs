//! bettimill-plan (being written).
