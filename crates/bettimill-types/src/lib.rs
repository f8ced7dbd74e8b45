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

/// The narrowest gap, in voxels, between two parts of one object that must stay apart
/// (the two sides of a hole, a shell's inside, two strands of a knot): it exceeds the
/// diagonal of a 4D voxel (2), so the foreground never bridges it, and the width a digital
/// plane needs to separate background in 4D. A manifest's `inner_gap` raises it.
pub const MIN_INNER_GAP: f64 = 2.5;
/// The widest `inner_gap` a manifest may ask for.
pub const MAX_INNER_GAP: f64 = 16.0;

/// The largest side of a 4D cube whose Betti numbers the exact route computes: with a
/// border of one voxel and each side rounded up to a multiple of 4, the image must have at
/// most 2^32 voxels (32-bit places; (254 + 2)^4 = 2^32). Manifests refuse larger 4D sides.
pub const MAX_4D_SIDE: usize = 254;
