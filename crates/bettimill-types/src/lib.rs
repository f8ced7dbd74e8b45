//! Plain types shared by the schema crates (manifest, plan, format) and the algorithms
//! that act on them (deform, homology).
//!
//! Architecture invariant: this crate depends on no other bettimill crate and holds no
//! algorithm. A schema crate reads and records these types without pulling in the code
//! that acts on them.

pub mod deform;

pub use deform::{
    DeformSettings, DeformStep, Deformation, Method, SettingError, Solid, Spread,
    DEFAULT_GROWTH_PROBABILITY, DEFAULT_MAX_DISTANCE, DEFAULT_NOISE_FREQUENCY, DEFAULT_OCTAVES,
    MAX_CLEARANCE, MAX_COUNT, MAX_DISTANCE, MAX_OCTAVES, MAX_STEPS,
};

/// The largest side of a 4D cube whose Betti numbers the exact route computes: with a
/// border of one voxel and each side rounded up to a multiple of 4, the image must have at
/// most 2^32 voxels (32-bit places; (254 + 2)^4 = 2^32). Manifests refuse larger 4D sides.
pub const MAX_4D_SIDE: usize = 254;
