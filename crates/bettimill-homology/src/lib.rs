//! Exact topology of binary images: Betti numbers over Z/2 and the simple-point test.
//!
//! The model (shared with every other bettimill crate) is the union of the closed unit
//! voxels of the foreground: foreground voxels touching at a corner are connected
//! ((3^d-1)-adjacency), background voxels only through a shared (d-1)-face (2d-adjacency),
//! and everything outside the image is background. [`simple`] decides whether one voxel can
//! be flipped without changing that topology; it is the kernel of both deformations.

pub mod simple;
