//! Exact topology of binary images: Betti numbers over Z/2 and the simple-point test.
//!
//! The model (shared with every other bettimill crate) is the union of the closed unit
//! voxels of the foreground: foreground voxels touching at a corner are connected
//! ((3^d-1)-adjacency), background voxels only through a shared (d-1)-face (2d-adjacency),
//! and everything outside the image is background. Labels are only worth something if they
//! are exact, so [`topology`] computes homology, not an estimate, and [`mod@reference`] is a
//! slow, obviously correct oracle the tests hold it against.
//!
//! How [`topology`] gets there cheaply:
//! - b_0 counts foreground components, b_{d-1} counts background components of the padded
//!   image minus one, and the Euler characteristic is a streaming sum over grid vertices;
//!   in 2D and 3D that determines everything (b_1 = b_0 + b_2 - chi in 3D).
//! - In 4D b_1 and b_2 are tied by one equation only, so the image is thinned by sequential
//!   simple-point deletion, a raster sweep and then the voxels whose neighbourhood changed
//!   (same homotopy type; about 1% of a blob's voxels survive), and the remnant's cubical
//!   complex is shrunk by collapses and coreductions (module `dense`) until the cells left
//!   go to an explicit Z/2 rank, by elimination with free pivots first (module
//!   `eliminate`): a few cells on a smooth image, over a million on some random ones, where
//!   a plain column reduction was quadratic.
//! - For a solid cube with cavities (a foreground wall encloses all inner background), 4D
//!   thinning would leave a 3-dimensional shell around every cavity. Instead the background
//!   is thinned (its simple voxels are given to the object) down to thin cores of the
//!   cavities, and duality (labels note) turns the cores' homology in the other
//!   construction into the object's: the cost follows the cavities, which are small, not
//!   the wall.
//!
//! Memory: the padded copy (one byte per voxel; [`try_topology_owned`] makes it from the
//! caller's image in place, [`try_topology`] beside it) and the survivors of the thinning
//! (four bytes each), then the remnant's complex (two bytes per voxel of address space,
//! in 2 MiB pages backed only where the remnant is; four per owner voxel when they are
//! few enough to list; five per queued cell, one per free face found by the first scan and
//! about three per candidate in a long queue),
//! and on a rough image the elimination's lists of the cells the pairs leave. So the peak
//! is a few bytes per voxel, more on random images, whose remnant is most of the image
//! (figures per size in BENCHMARKS.md).
//! On a large remnant the reduction pairs run on two threads, in parts of the grid that
//! never meet (module `dense`).
//!
//! [`simple`] decides whether one voxel can be flipped without changing the topology; it is
//! the kernel of both deformations and of the thinning.

mod complex;
mod components;
mod dense;
mod eliminate;
mod euler;
pub mod reference;
pub mod simple;
mod thin;

use bettimill_grid::neighbourhood::{face_offsets, flat_offsets};
use bettimill_grid::{BinaryImage, Dim};
use dense::{DenseComplex, FinalRank};
use eliminate::rank_by_elimination;
use serde::{Deserialize, Serialize};
use thin::Phase;

/// The homology of one image: Betti numbers b_0..b_{d-1} over Z/2 and the Euler
/// characteristic (their alternating sum, stored because it is a cheap cross-check).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Topology {
    /// b_k for k = 0..d-1; `betti.len()` is the image dimension.
    pub betti: Vec<u64>,
    /// sum over k of (-1)^k b_k.
    pub euler: i64,
}

impl Topology {
    fn from_betti(betti: Vec<u64>) -> Topology {
        let euler = betti
            .iter()
            .enumerate()
            .map(|(k, &b)| if k % 2 == 0 { b as i64 } else { -(b as i64) })
            .sum();
        Topology { betti, euler }
    }
}

/// The largest side of a 4D cube whose Betti numbers [`try_topology`] computes (one
/// definition, in the leaf crate the manifest also reads); larger is
/// [`TopologyError::TooLarge`].
pub use bettimill_types::MAX_4D_SIDE;

/// Why [`try_topology`] computed no Betti numbers.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TopologyError {
    /// The cells left after the reduction pairs are too many for the elimination's lists:
    /// one of its pools would pass 2^32 - 1 entries (its places and lengths are 32-bit).
    /// Only a huge rough 4D image gets there (hundreds of voxels a side, over 16 GiB of
    /// lists); nothing is computed rather than something wrong.
    #[error(
        "the image is too large and rough for the exact rank: the cells left after the \
         reduction pairs need a list pool of {needed} entries, over its limit of {limit} \
         (crop or split the image)"
    )]
    TooRough {
        /// The entries the pool would have needed.
        needed: u64,
        /// The most a pool holds.
        limit: u64,
    },
    /// A 4D image too large for the exact route's 32-bit places: with a border of one voxel
    /// and each side rounded up to a multiple of 4, it has more than 2^32 voxels (a cube
    /// over [`MAX_4D_SIDE`] a side, or a very long thin image).
    #[error(
        "the 4D image is too large for the exact route: {places} voxels with its border, \
         each side rounded up to a multiple of 4, over 2^32 (crop or split the image)"
    )]
    TooLarge {
        /// The voxels the complex's grid would have.
        places: u64,
    },
}

impl From<dense::GridTooLarge> for TopologyError {
    fn from(grid: dense::GridTooLarge) -> TopologyError {
        TopologyError::TooLarge {
            places: grid.places,
        }
    }
}

impl From<eliminate::PoolOverflow> for TopologyError {
    fn from(overflow: eliminate::PoolOverflow) -> TopologyError {
        TopologyError::TooRough {
            needed: overflow.needed,
            limit: overflow.limit,
        }
    }
}

/// The exact Betti numbers (over Z/2) and Euler characteristic of `image`.
///
/// ```
/// use bettimill_grid::BinaryImage;
/// use bettimill_homology::topology;
///
/// // A 3x3x3 cube with its centre voxel removed: one piece around one cavity.
/// let mut image = BinaryImage::from_vec(&[3, 3, 3], vec![1; 27]).unwrap();
/// image.set(&[1, 1, 1], false);
/// let t = topology(&image);
/// assert_eq!(t.betti, [1, 0, 1]);
/// assert_eq!(t.euler, 2);
///
/// // In 4D: a 5x5 square one voxel thick along the last two axes, its centre removed, is
/// // a loop.
/// let mut ring = BinaryImage::from_vec(&[5, 5, 1, 1], vec![1; 25]).unwrap();
/// ring.set(&[2, 2, 0, 0], false);
/// assert_eq!(topology(&ring).betti, [1, 1, 0, 0]);
/// ```
///
/// # Panics
///
/// When [`try_topology`] returns an error: only on a 4D image too large for 32-bit places
/// ([`TopologyError::TooLarge`]) or too large and rough for the elimination's 32-bit lists
/// ([`TopologyError::TooRough`]). Callers with images from
/// outside (the CLI) call [`try_topology`].
pub fn topology(image: &BinaryImage) -> Topology {
    try_topology(image).unwrap_or_else(|error| panic!("{error}"))
}

/// The exact Betti numbers (over Z/2) and Euler characteristic of `image`, or an error when
/// they cannot be computed exactly ([`TopologyError`]).
pub fn try_topology(image: &BinaryImage) -> Result<Topology, TopologyError> {
    let route = Route::of(image, 0)?;
    route.run(image.padded(1))
}

/// [`try_topology`] of an image the caller gives up: it is padded in place
/// ([`BinaryImage::into_padded`]), so the peak memory holds one copy of the image instead
/// of two (a 128^4 image is 268 MB).
pub fn try_topology_owned(image: BinaryImage) -> Result<Topology, TopologyError> {
    let route = Route::of(&image, 0)?;
    route.run(image.into_padded(1))
}

/// [`try_topology`] of the image whose copy with a background border of one voxel is
/// `padded` ([`BinaryImage::padded`]; `bettimill betti` reads a file straight into it). If
/// its border is not background after all, it is padded again: more background changes no
/// homology.
pub fn try_topology_padded(padded: BinaryImage) -> Result<Topology, TopologyError> {
    if !padded.border_is_background() {
        return try_topology_owned(padded);
    }
    let route = Route::of(&padded, 1)?;
    route.run(padded)
}

/// How [`try_topology`] computes an image's homology, decided on the image before it is
/// padded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Route {
    /// 2D and 3D: components and the Euler characteristic.
    Counts,
    /// 4D: thin the object, then reduce the remnant's complex.
    Thinning,
    /// 4D, a solid cube with cavities: thin the background (see below).
    Background,
}

impl Route {
    /// The route of `image`, or of the image inside its border of `border` (0 or 1) layers.
    fn of(image: &BinaryImage, border: usize) -> Result<Route, TopologyError> {
        debug_assert!(border <= 1);
        if image.dim() != Dim::Four {
            return Ok(Route::Counts);
        }
        // Checked before the padded copy and the thinning, which would be wasted.
        let padded_shape: Vec<usize> = image.shape().iter().map(|&n| n + 2 - 2 * border).collect();
        dense::check_grid(&padded_shape)?;
        // A solid cube with cavities (a foreground wall around everything that is
        // background inside it) goes through its background: the cavities thin to thin
        // cores, where thinning the object would leave a 3-dimensional shell around every
        // cavity. Anything else (objects in empty space, blobs) thins the object; its
        // background stays attached to the border, where the background route would fall
        // back and pay twice.
        Ok(if has_foreground_wall(image, border) {
            Route::Background
        } else {
            Route::Thinning
        })
    }

    /// The homology of the image whose copy with a background border of one voxel is
    /// `padded`.
    fn run(self, padded: BinaryImage) -> Result<Topology, TopologyError> {
        match self {
            Route::Counts => Ok(topology_from_counts(&padded)),
            Route::Thinning => topology_by_thinning(padded),
            Route::Background => topology_by_background(padded),
        }
    }
}

/// 2D and 3D: components of both phases plus the Euler characteristic.
fn topology_from_counts(padded: &BinaryImage) -> Topology {
    let d = padded.dim().get();
    let chi = euler::euler_characteristic(padded);
    let b0 = components::count_components(padded, 1);
    let top = components::count_components(padded, 0) - 1;
    let betti = if d == 2 {
        // b1 = top here, so chi = b0 - b1 is a genuine cross-check below.
        vec![b0, top]
    } else {
        // chi = b0 - b1 + b2.
        vec![b0, (b0 as i64 + top as i64 - chi) as u64, top]
    };
    let topology = Topology::from_betti(betti);
    debug_assert_eq!(topology.euler, chi);
    topology
}

/// Any dimension: thin, then explicit homology of the remnant. `padded` must have a
/// background border.
fn topology_by_thinning(padded: BinaryImage) -> Result<Topology, TopologyError> {
    Ok(topology_by_thinning_with(padded, rank_by_elimination)?.0)
}

/// [`topology_by_thinning`] with the remnant's final rank computed as `final_rank` says;
/// also returns how many general pivots the elimination took.
fn topology_by_thinning_with(
    mut padded: BinaryImage,
    final_rank: FinalRank,
) -> Result<(Topology, u64), TopologyError> {
    let d = padded.dim().get();
    let tester = simple::SimpleTester::new(padded.dim());
    let remaining = thin::thin(&mut padded, &tester, Phase::Foreground);
    let steps = flat_offsets(&padded, tester.offsets());
    let b0 = components::count_components_of(padded.data_mut(), &remaining, &steps);
    let complex = remnant_complex(&padded, &remaining, &tester)?;
    // The image and the survivors' list are not needed by the reduction: freed before its
    // lists are built (a random image's peak).
    drop(remaining);
    drop(padded);
    let (mut betti, general) = complex.betti_with(b0, final_rank)?;
    betti.truncate(d);
    Ok((Topology::from_betti(betti), general))
}

/// The complex of the union of the closed voxels `remaining` (the only foreground of
/// `padded`), minus what collapses inside single voxels. A cell of voxel v that no other
/// voxel of the union contains (a private cell) has all its cofaces in v too, so free-face
/// collapses among v's private cells are collapses of the whole complex; they are done per
/// voxel on 81-bit masks (the voxel and its 80 boundary faces, the shared ones, v's
/// attachment set, held fixed), and only the shared cells and the private survivors enter
/// the complex. A voxel on a thin loop or sheet keeps a handful of private cells instead
/// of tens.
///
/// Each voxel's cells depend on the image alone, and its cells are owned by it and by
/// voxels one step back. So the voxels are cut in two at a brick row (the one that halves
/// them) and each half is done on its own thread, in the voxels' order: each inserts the
/// cells owned on its side of the cut, and the few that the second half's first plane owns
/// one step back, on the first half's side, are inserted after both. The complex is the
/// same whatever the threads' timing. (The masks live in huge pages: two threads filling
/// fresh masks at once in 4 KiB pages take thousands of page faults, in huge pages a few.)
fn remnant_complex(
    padded: &BinaryImage,
    remaining: &[u32],
    tester: &simple::SimpleTester,
) -> Result<DenseComplex, dense::GridTooLarge> {
    Ok(remnant_complex_cut(padded, remaining, tester, 1 << 11)?.0)
}

/// [`remnant_complex`], cut in two from `fewest` voxels (tests: the cut and the uncut
/// complex are the same), and how many masks the second half held back.
fn remnant_complex_cut(
    padded: &BinaryImage,
    remaining: &[u32],
    tester: &simple::SimpleTester,
    fewest: usize,
) -> Result<(DenseComplex, usize), dense::GridTooLarge> {
    let offsets = tester.offsets();
    let n = offsets.len();
    let cell_bit = 1u128 << n;
    let every_face = cell_bit - 1;
    let cofaces = tester.cofaces_with_cell();
    // Each face's facets among the faces (entry n: the voxel's), and the faces by
    // dimension, highest first: the layers of the collapse below.
    let mut facets = vec![0u128; n + 1];
    for (f, mut up) in cofaces.iter().copied().enumerate() {
        while up != 0 {
            facets[up.trailing_zeros() as usize] |= 1 << f;
            up &= up - 1;
        }
    }
    let d = padded.dim().get();
    let layers: Vec<u128> = (1..=d)
        .map(|across| {
            (0..n)
                .filter(|&f| offsets[f].iter().filter(|&&o| o != 0).count() == across)
                .fold(0u128, |layer, f| layer | 1 << f)
        })
        .collect();
    let mut complex = DenseComplex::new(padded.shape())?;
    // A rough remnant (survivors in one place of 16 or more; a random 64^4 image's are
    // one in four) gives nearly every place cells: its owners are scanned, not listed.
    if remaining.len() >= complex.places() / 16 {
        complex = complex.unlisted();
    }
    let complex_listed = complex.lists_owners();
    let grid = *complex.grid();
    let places = grid.face_places(offsets);
    let strides = padded.strides().to_vec();
    let data = padded.data();
    // The cells a voxel whose attachment set is `shared` puts in the complex, as the masks
    // of the voxels that own them (entry s is the voxel one step back along the axes in s,
    // as `Grid::owners_around` lists them): they depend on that set alone.
    let masks_of = |shared: u128| -> [u16; 16] {
        // Private cells: the voxel itself and the boundary faces no neighbour shares.
        let mut alive = cell_bit | (every_face & !shared);
        // Free-face collapses, one dimension of free face at a time, highest first. A
        // collapse of (f, c) with f of dimension k removes a k-face and a (k + 1)-face, so
        // it can only free the other k-facets of c (they are tried again) and never a
        // face of a higher layer: after the last layer no private face is free.
        for &layer in &layers {
            let mut todo = alive & layer;
            while todo != 0 {
                let f = todo.trailing_zeros() as usize;
                todo &= todo - 1;
                debug_assert!(alive >> f & 1 == 1, "only alive faces are queued");
                let up = cofaces[f] & alive;
                // One coface (`count_ones` is a dozen instructions on baseline x86-64).
                if up != 0 && up & (up - 1) == 0 {
                    alive &= !(1u128 << f) & !up;
                    todo |= facets[up.trailing_zeros() as usize] & alive & layer;
                }
            }
        }
        let mut masks = [0u16; 16];
        let mut emit = (shared | alive) & every_face;
        while emit != 0 {
            let f = emit.trailing_zeros() as usize;
            emit &= emit - 1;
            let (back, code) = places[f];
            masks[back] |= 1 << code;
        }
        if alive & cell_bit != 0 {
            masks[0] |= 1;
        }
        masks
    };
    let owned = 1 << padded.dim().get();
    let insert = |voxels: &[u32], inserter: &mut dense::Inserter| {
        // A smooth image's remnant repeats some local shapes: each thread keeps the masks
        // of the attachment sets it met last, and a hit skips the collapses. A rough
        // image's sets repeat too rarely to pay for the memo, so it has none.
        let mut memo = complex_listed.then(MasksMemo::new);
        for &index in voxels {
            let index = index as usize;
            let config = tester.configuration_in(data, &strides, index);
            let shared = tester.attachment_of(config);
            let masks = match &mut memo {
                Some(memo) => memo.get(shared, masks_of),
                None => masks_of(shared),
            };
            let place = grid.place(&padded.coords(index));
            let around = grid.owners_around(place);
            for (&owner, &mask) in around.iter().zip(&masks).take(owned) {
                if mask != 0 {
                    inserter.insert_mask(owner, mask);
                }
            }
        }
    };
    // The cut: at the brick row of the middle voxel (the voxels are in raster order, so in
    // order of their first coordinate); none for a few voxels.
    let row = |i: u32| padded.coords(i as usize)[0] / 4;
    let cut = match remaining.len() {
        n if n < fewest.max(1) => 0,
        n => remaining.partition_point(|&i| row(i) < row(remaining[n / 2])),
    };
    let boundary = match cut {
        0 => 0,
        _ => grid.row_start(grid.place(&padded.coords(remaining[cut] as usize))),
    };
    let (lower, upper) = remaining.split_at(cut);
    let held = complex.insert_split(boundary, |a| insert(lower, a), |b| insert(upper, b));
    Ok((complex, held))
}

/// A direct-mapped memo of [`remnant_complex_cut`]'s masks by attachment set (a pure
/// function memoised: it cannot change a result).
struct MasksMemo {
    /// Per slot: the attachment set with bit 127 set (0: empty; a set has 80 bits at most),
    /// and its masks.
    slots: Vec<(u128, [u16; 16])>,
}

impl MasksMemo {
    /// 2^10 slots of 48 bytes, 48 KiB a thread.
    const BITS: u32 = 10;
    const USED: u128 = 1 << 127;

    fn new() -> MasksMemo {
        MasksMemo {
            slots: vec![(0, [0; 16]); 1 << Self::BITS],
        }
    }

    /// The masks of the attachment set `shared`, computed by `masks_of` on a miss.
    #[inline]
    fn get(&mut self, shared: u128, masks_of: impl Fn(u128) -> [u16; 16]) -> [u16; 16] {
        debug_assert_eq!(shared & Self::USED, 0);
        let slot = (simple::mix(shared) >> (64 - Self::BITS)) as usize;
        let (key, masks) = &mut self.slots[slot];
        if *key != shared | Self::USED {
            *key = shared | Self::USED;
            *masks = masks_of(shared);
        }
        *masks
    }
}

/// Any dimension, through the background: the object's Betti numbers are those of the
/// padded background in the other construction (voxel centres as vertices, 2d-adjacency),
/// re-indexed (labels note: b_0 = b_{d-1}(bg), b_k = b_{d-1-k}(bg), b_{d-1} = b_0(bg) - 1).
///
/// The background is thinned first by giving its simple voxels to the object (no topology
/// changes on either side), with the outer layer of `padded` locked. What is left is that
/// layer (the frame) and thin cores of the inner background components. If no core touches
/// the frame through a face, the frame is a component of its own with the homology of a
/// (d-1)-sphere, and only the cores need an explicit complex: small, where thinning the
/// object would leave a shell around every cavity. Otherwise the grown object (same
/// topology) goes through [`topology_by_thinning`].
fn topology_by_background(padded: BinaryImage) -> Result<Topology, TopologyError> {
    match background_cores(padded, rank_by_elimination)? {
        Ok(topology) => Ok(topology),
        Err(grown) => topology_by_thinning(grown),
    }
}

/// [`topology_by_background`] up to the fallback: the inner Err holds the grown object
/// (same topology as the input) when a core of the background touches the frame.
fn background_cores(
    mut padded: BinaryImage,
    final_rank: FinalRank,
) -> Result<Result<Topology, BinaryImage>, TopologyError> {
    let d = padded.dim().get();
    let shape = padded.shape().to_vec();
    // Complement, and lock the outer layer (value 5).
    for v in padded.data_mut().iter_mut() {
        *v ^= 1;
    }
    lock_border(&mut padded);
    let tester = simple::SimpleTester::new(padded.dim());
    let cores = thin::thin(&mut padded, &tester, Phase::Background);
    let strides = padded.strides().to_vec();
    let data = padded.data();
    let touches_frame = cores.iter().map(|&i| i as usize).any(|i| {
        strides
            .iter()
            .any(|&s| data[i - s] & 4 != 0 || data[i + s] & 4 != 0)
    });
    if touches_frame {
        for v in padded.data_mut().iter_mut() {
            *v = (*v & 1 == 0) as u8;
        }
        return Ok(Err(padded));
    }
    // The cores' cubical complex in the other construction: a cell (the unit cube spanned
    // by voxel centres v + {0,1}^S for a set S of axes) is present when all its corners
    // are. Its Khalimsky coordinates are 2 v_a + 1 along the axes of S and 2 v_a (even,
    // owned one voxel back: see `dense`) along the others.
    let mut complex = DenseComplex::new(&shape)?;
    let grid = *complex.grid();
    for i in cores.iter().map(|&i| i as usize) {
        let around = grid.owners_around(grid.place(&padded.coords(i)));
        'cubes: for subset in 0usize..1 << d {
            // Every corner v + sum of a subset T of S.
            let mut t = subset;
            loop {
                let offset: usize = (0..d)
                    .filter(|&a| t >> a & 1 == 1)
                    .map(|a| strides[a])
                    .sum();
                if data[i + offset] & 1 == 0 {
                    continue 'cubes;
                }
                if t == 0 {
                    break;
                }
                t = (t - 1) & subset;
            }
            let even = !subset & ((1 << d) - 1);
            complex.insert(around[even], even as u32);
        }
    }
    // Vertices are the cores' voxels and edges join face neighbours.
    let face_steps = flat_offsets(&padded, &face_offsets(padded.dim()));
    let b0 = components::count_components_of(padded.data_mut(), &cores, &face_steps);
    let inner = complex.betti_with(b0, final_rank)?.0;
    // The background: the frame (a (d-1)-sphere) plus the cores.
    let mut background = inner;
    background[0] += 1;
    background[d - 1] += 1;
    let mut betti = vec![0u64; d];
    betti[0] = background[d - 1];
    for k in 1..d - 1 {
        betti[k] = background[d - 1 - k];
    }
    betti[d - 1] = background[0] - 1;
    Ok(Ok(Topology::from_betti(betti)))
}

/// Whether the surface of some box nested in the image, at most a quarter of the side in
/// from the border, is all foreground: then the background inside it is cut off from the
/// border. Boxes that fail usually fail at their first voxels, and the one that succeeds
/// costs its surface (side^3 voxels per pair of faces), so this is cheap next to
/// homology. With `border` layers around the image (0 or 1: its padded copy), the boxes
/// are those of the image inside them.
fn has_foreground_wall(image: &BinaryImage, border: usize) -> bool {
    let shape = image.shape();
    let d = shape.len();
    let last = shape[d - 1];
    let depth = shape
        .iter()
        .min()
        .map_or(0, |&n| n.saturating_sub(2 * border))
        / 4;
    let data = image.data();
    (border..border + depth).any(|t| {
        let inside = |x: usize, n: usize| (t..n - t).contains(&x);
        let on_surface = |x: usize, n: usize| x == t || x + 1 == n - t;
        // Rows along the last axis: a row on a face of the box must be foreground from t
        // to last - 1 - t; any other row of the box only at its two ends.
        let rows = image.len() / last;
        let per_plane = rows / shape[0];
        (t * per_plane..(shape[0] - t) * per_plane).all(|row| {
            let mut rest = row;
            let mut within = true;
            let mut face = false;
            for a in (0..d - 1).rev() {
                let x = rest % shape[a];
                rest /= shape[a];
                within &= inside(x, shape[a]);
                face |= on_surface(x, shape[a]);
            }
            if !within {
                return true;
            }
            let line = &data[row * last + t..row * last + last - t];
            if face {
                line.iter().all(|&v| v != 0)
            } else {
                line[0] != 0 && line[line.len() - 1] != 0
            }
        })
    })
}

/// Sets every voxel of the outer layer to 5 (locked, background phase).
fn lock_border(image: &mut BinaryImage) {
    let shape = image.shape().to_vec();
    let d = shape.len();
    let last = shape[d - 1];
    let rows = image.len() / last;
    let data = image.data_mut();
    for row in 0..rows {
        // The coordinates of the row's first d - 1 axes.
        let mut rest = row;
        let mut on_border = false;
        for a in (0..d - 1).rev() {
            let x = rest % shape[a];
            rest /= shape[a];
            on_border |= x == 0 || x + 1 == shape[a];
        }
        let line = &mut data[row * last..(row + 1) * last];
        if on_border {
            line.fill(5);
        } else {
            line[0] = 5;
            line[last - 1] = 5;
        }
    }
}

#[cfg(test)]
mod tests;
