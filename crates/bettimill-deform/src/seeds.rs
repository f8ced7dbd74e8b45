//! Seed objects to grow: curves, circles, knots, bridges, tentacles, thin spheres and tori.
//!
//! The morphology of the paper starts from thin seed objects and grows them with
//! topology-preserving dilation, so the grown sample has the seed's Betti numbers. This
//! module draws seeds and knows their Betti numbers exactly, by construction:
//!
//! - Curves, circles, knots, bridges and tentacles are drawn one voxel at a time, and each
//!   voxel is classified by the simple-point test before it is added. A voxel with no
//!   foreground neighbour starts a component (b0 + 1); a simple voxel changes nothing; a
//!   voxel whose attachment set is two acyclic pieces either closes a loop (b1 + 1, both
//!   pieces in the same component) or joins two components (b0 - 1). The last rule is
//!   Mayer-Vietoris with an attachment set of two contractible pieces; whether the pieces
//!   are in the same component is read from a union-find over object labels. Any other
//!   voxel ends the object (curves, tentacles) or undoes it (circles, knots, bridges).
//!   The components of the attachment set are those of the foreground neighbours under
//!   (3^d-1)-adjacency, because two neighbours' faces on the cube meet exactly when the
//!   neighbours are adjacent.
//! - Thin 2-spheres and tori (3D and 4D) are shells rasterised in a small 3D box whose
//!   Betti numbers are checked with `bettimill_homology::topology` ((1,0,1) and (1,2,1));
//!   in 4D the box becomes one voxel thick along the fourth axis, which does not change
//!   its homotopy type (the union of closed voxels is the 3D union times an interval).
//!   A shell is only placed where its whole 3^d neighbourhood is background, so it is a
//!   new component and its Betti numbers add.
//!
//! Everything is drawn at least [`MARGIN`] voxels from the faces of the image, so growth
//! has room before the never-edited outer layer. Placement is random (a `ChaCha8Rng`
//! seeded by the caller) and failed placements are retried a bounded number of times, so
//! a scene may hold fewer objects than asked for; [`Scene::placed`] says how many.

use crate::moves::index_below;
use crate::DeformError;
use bettimill_grid::neighbourhood::{flat_offsets, full_offsets};
use bettimill_grid::BinaryImage;
use bettimill_homology::simple::SimpleTester;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Seeds keep at least this many voxels between themselves and every face of the image.
pub const MARGIN: usize = 2;

/// Placement attempts per requested object before giving up on it.
const ATTEMPTS: usize = 40;

/// Curve sampling step in voxels: below 1 in every coordinate, so consecutive rounded
/// points are neighbours (or equal).
const STEP: f64 = 0.5;

/// How many of each object a scene asks for (or, in [`Scene::placed`], got).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneSpec {
    /// Open curves (each a contractible component).
    pub curves: u32,
    /// Circles in random planes (b0 + 1, b1 + 1 each).
    pub circles: u32,
    /// Trefoil knots in random 3D subspaces, 3D and 4D only (b0 + 1, b1 + 1 each).
    pub knots: u32,
    /// Curves joining two different components (b0 - 1 each): connected circles.
    pub bridges: u32,
    /// Curves growing out of an existing object (no change).
    pub tentacles: u32,
    /// Thin 2-spheres, 3D and 4D only (b0 + 1, b2 + 1 each).
    pub spheres: u32,
    /// Thin tori, 3D and 4D only (b0 + 1, b1 + 2, b2 + 1 each).
    pub tori: u32,
}

/// A seed image and its exact Betti numbers.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// The seeds.
    pub image: BinaryImage,
    /// b_0 .. b_{d-1} of `image`.
    pub betti: Vec<u64>,
    /// How many objects of each kind were placed.
    pub placed: SceneSpec,
}

/// How one added voxel changes the topology.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Event {
    NewComponent,
    Simple,
    Loop,
    Merge(u32, u32),
    Other,
}

/// Draws seed objects into an image while tracking its Betti numbers exactly.
pub struct SeedBuilder {
    image: BinaryImage,
    // Object label per voxel (0 = background); labels are union-find nodes.
    labels: Vec<u32>,
    parent: Vec<u32>,
    // Voxels drawn under each label, for picking attachment points.
    voxels_of: Vec<Vec<usize>>,
    betti: Vec<i64>,
    tester: SimpleTester,
    neighbour_flat: Vec<isize>,
    neighbour_adjacency: Vec<u128>,
    rng: ChaCha8Rng,
}

/// What an object under construction needs to be undone.
struct Transaction {
    added: Vec<usize>,
    betti: Vec<i64>,
    parent_len: usize,
    parent: Vec<u32>,
}

fn unit_vector(rng: &mut ChaCha8Rng, d: usize) -> [f64; 4] {
    loop {
        let mut v = [0.0f64; 4];
        for c in v.iter_mut().take(d) {
            *c = rng.gen_range(-1.0..1.0);
        }
        let norm = libm::sqrt(v.iter().map(|c| c * c).sum());
        if (0.1..=1.0).contains(&norm) {
            return v.map(|c| c / norm);
        }
    }
}

/// `k` random orthonormal vectors (Gram-Schmidt on random unit vectors).
fn orthonormal(rng: &mut ChaCha8Rng, d: usize, k: usize) -> Vec<[f64; 4]> {
    let mut basis: Vec<[f64; 4]> = Vec::with_capacity(k);
    while basis.len() < k {
        let mut v = unit_vector(rng, d);
        for b in &basis {
            let dot: f64 = (0..4).map(|a| v[a] * b[a]).sum();
            for a in 0..4 {
                v[a] -= dot * b[a];
            }
        }
        let norm = libm::sqrt(v.iter().map(|c| c * c).sum());
        if norm > 0.3 {
            basis.push(v.map(|c| c / norm));
        }
    }
    basis
}

impl SeedBuilder {
    /// An empty image of `shape` to draw into; every axis needs at least `2 * MARGIN + 3`
    /// voxels.
    pub fn new(shape: &[usize], seed: u64) -> Result<SeedBuilder, DeformError> {
        let image = BinaryImage::zeros(shape).map_err(|e| DeformError::InvalidSetting {
            field: "shape",
            reason: e.to_string(),
        })?;
        if shape.iter().any(|&n| n < 2 * MARGIN + 3) {
            return Err(DeformError::InvalidSetting {
                field: "shape",
                reason: format!(
                    "seeds need at least {} voxels along every axis, got {shape:?}",
                    2 * MARGIN + 3
                ),
            });
        }
        let dim = image.dim();
        let offsets = full_offsets(dim);
        let neighbour_adjacency = offsets
            .iter()
            .map(|a| {
                offsets
                    .iter()
                    .enumerate()
                    .filter(|(_, b)| *b != a && (0..4).all(|k| (a[k] - b[k]).abs() <= 1))
                    .fold(0u128, |m, (j, _)| m | 1 << j)
            })
            .collect();
        Ok(SeedBuilder {
            neighbour_flat: flat_offsets(&image, &offsets),
            labels: vec![0; image.len()],
            parent: vec![0],
            voxels_of: vec![Vec::new()],
            betti: vec![0; dim.get()],
            tester: SimpleTester::new(dim),
            neighbour_adjacency,
            rng: ChaCha8Rng::seed_from_u64(seed),
            image,
        })
    }

    /// The image drawn so far.
    pub fn image(&self) -> &BinaryImage {
        &self.image
    }

    /// Exact Betti numbers b_0 .. b_{d-1} of the image drawn so far.
    pub fn betti(&self) -> Vec<u64> {
        self.betti.iter().map(|&b| b as u64).collect()
    }

    /// The image and its Betti numbers.
    pub fn finish(self) -> (BinaryImage, Vec<u64>) {
        let betti = self.betti();
        (self.image, betti)
    }

    fn dim(&self) -> usize {
        self.image.dim().get()
    }

    fn find(&self, mut label: u32) -> u32 {
        while self.parent[label as usize] != label {
            label = self.parent[label as usize];
        }
        label
    }

    /// The voxel nearest to `p`, if it lies at least [`MARGIN`] from every face.
    fn voxel(&self, p: [f64; 4]) -> Option<usize> {
        let shape = self.image.shape();
        let mut c = [0usize; 4];
        for a in 0..self.dim() {
            let r = libm::floor(p[a] + 0.5);
            if r < MARGIN as f64 || r > (shape[a] - 1 - MARGIN) as f64 {
                return None;
            }
            c[a] = r as usize;
        }
        Some(self.image.index(&c[..self.dim()]))
    }

    /// Rounds points to voxels, dropping consecutive repeats; `None` if one is outside.
    fn rasterise(&self, points: &[[f64; 4]]) -> Option<Vec<usize>> {
        let mut out: Vec<usize> = Vec::with_capacity(points.len());
        for &p in points {
            let v = self.voxel(p)?;
            if out.last() != Some(&v) {
                out.push(v);
            }
        }
        Some(out)
    }

    /// A random point at least `extent` voxels inside the drawable region, so an object
    /// of that radius fits around it; `None` if the image is too small for that.
    fn random_point(&mut self, extent: f64) -> Option<[f64; 4]> {
        let mut p = [0.0f64; 4];
        for (a, c) in p.iter_mut().enumerate().take(self.dim()) {
            let n = self.image.shape()[a];
            let (lo, hi) = (MARGIN as f64 + extent, (n - 1 - MARGIN) as f64 - extent);
            if lo >= hi {
                return None;
            }
            *c = self.rng.gen_range(lo..hi);
        }
        Some(p)
    }

    fn classify(&self, z: usize) -> Event {
        let config = self.tester.configuration(&self.image, z);
        if config == 0 {
            return Event::NewComponent;
        }
        if self.tester.is_simple_configuration(config) {
            return Event::Simple;
        }
        // Split the foreground neighbours into their (3^d-1)-components.
        let mut rest = config;
        let mut pieces = Vec::with_capacity(2);
        while rest != 0 {
            let mut piece = rest & rest.wrapping_neg();
            loop {
                let mut grown = piece;
                let mut bits = piece;
                while bits != 0 {
                    let k = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    grown |= self.neighbour_adjacency[k] & config;
                }
                if grown == piece {
                    break;
                }
                piece = grown;
            }
            rest &= !piece;
            pieces.push(piece);
            if pieces.len() > 2 {
                return Event::Other;
            }
        }
        if pieces.len() != 2
            || !pieces
                .iter()
                .all(|&p| self.tester.is_simple_configuration(p))
        {
            return Event::Other;
        }
        let root = |piece: u128| {
            let k = piece.trailing_zeros() as usize;
            let v = (z as isize + self.neighbour_flat[k]) as usize;
            self.find(self.labels[v])
        };
        let (a, b) = (root(pieces[0]), root(pieces[1]));
        if a == b {
            Event::Loop
        } else {
            Event::Merge(a, b)
        }
    }

    fn begin(&self) -> Transaction {
        Transaction {
            added: Vec::new(),
            betti: self.betti.clone(),
            parent_len: self.parent.len(),
            parent: self.parent.clone(),
        }
    }

    fn rollback(&mut self, t: Transaction) {
        // `add` pushed each voxel onto its label's list, so undoing in reverse order pops
        // exactly those entries.
        for &v in t.added.iter().rev() {
            let popped = self.voxels_of[self.labels[v] as usize].pop();
            debug_assert_eq!(popped, Some(v), "voxel lists are undone in push order");
            self.image.data_mut()[v] = 0;
            self.labels[v] = 0;
        }
        self.parent = t.parent;
        self.voxels_of.truncate(t.parent_len);
        self.betti = t.betti;
    }

    /// Adds `z`, whose classification is `event`, updating labels and Betti numbers.
    fn add(&mut self, t: &mut Transaction, z: usize, event: Event) {
        let label = match event {
            Event::NewComponent => {
                let id = self.parent.len() as u32;
                self.parent.push(id);
                self.voxels_of.push(Vec::new());
                self.betti[0] += 1;
                id
            }
            Event::Simple | Event::Loop => {
                let config = self.tester.configuration(&self.image, z);
                let k = config.trailing_zeros() as usize;
                let v = (z as isize + self.neighbour_flat[k]) as usize;
                if event == Event::Loop {
                    self.betti[1] += 1;
                }
                self.find(self.labels[v])
            }
            Event::Merge(a, b) => {
                let (keep, gone) = (a.min(b), a.max(b));
                self.parent[gone as usize] = keep;
                self.betti[0] -= 1;
                keep
            }
            Event::Other => {
                unreachable!("voxels that change topology unpredictably are never added")
            }
        };
        self.image.data_mut()[z] = 1;
        self.labels[z] = label;
        self.voxels_of[label as usize].push(z);
        t.added.push(z);
    }

    /// A random smooth walk of about `length` voxels from `start`.
    fn walk(&mut self, start: [f64; 4], length: usize) -> Vec<[f64; 4]> {
        let d = self.dim();
        let mut p = start;
        let mut dir = unit_vector(&mut self.rng, d);
        let mut out = vec![p];
        for _ in 0..(length as f64 / STEP) as usize {
            let wiggle = unit_vector(&mut self.rng, d);
            let mut next = [0.0; 4];
            for a in 0..d {
                next[a] = dir[a] + 0.35 * wiggle[a];
            }
            let norm = libm::sqrt(next.iter().map(|c| c * c).sum());
            dir = next.map(|c| c / norm);
            for a in 0..d {
                p[a] += STEP * dir[a];
            }
            out.push(p);
        }
        out
    }

    /// Draws an open path voxel by voxel from its first background voxel, stopping at the
    /// first voxel that would change topology. `start_root` is the object the path must
    /// leave from (tentacles) or `None` for a new component (curves).
    fn draw_open(&mut self, path: &[usize], start_root: Option<u32>, min_len: usize) -> bool {
        let mut t = self.begin();
        let mut i = 0;
        if let Some(root) = start_root {
            // Skip the part of the path inside the object it grows from.
            while i < path.len()
                && self.image.data()[path[i]] == 1
                && self.find(self.labels[path[i]]) == root
            {
                i += 1;
            }
            if i == 0 {
                return false;
            }
        }
        for (k, &z) in path[i..].iter().enumerate() {
            if self.image.data()[z] == 1 {
                break;
            }
            let event = self.classify(z);
            let fine = match (k, start_root) {
                (0, None) => event == Event::NewComponent,
                _ => event == Event::Simple,
            };
            if !fine {
                break;
            }
            self.add(&mut t, z, event);
        }
        if t.added.len() < min_len {
            self.rollback(t);
            return false;
        }
        true
    }

    /// Draws a closed path; kept only if it closes exactly one loop and touches nothing.
    fn draw_closed(&mut self, path: &[usize]) -> bool {
        let mut path = path.to_vec();
        while path.len() > 1 && path.last() == path.first() {
            path.pop();
        }
        if path.len() < 8 {
            return false;
        }
        let mut t = self.begin();
        let mut loops = 0;
        let mut ok = true;
        for (k, &z) in path.iter().enumerate() {
            if self.image.data()[z] == 1 {
                // A repeated voxel of this path is harmless; anything else is contact.
                if t.added.contains(&z) {
                    continue;
                }
                ok = false;
                break;
            }
            let event = self.classify(z);
            match (k, event) {
                (0, Event::NewComponent) | (1.., Event::Simple) => {}
                (1.., Event::Loop) => loops += 1,
                _ => {
                    ok = false;
                    break;
                }
            }
            self.add(&mut t, z, event);
        }
        if !ok || loops != 1 {
            self.rollback(t);
            return false;
        }
        true
    }

    fn closed_curve(&mut self, f: impl Fn(f64) -> [f64; 4], length_hint: f64) -> bool {
        let n = (length_hint / (0.5 * STEP)).max(16.0) as usize;
        let points: Vec<[f64; 4]> = (0..=n)
            .map(|i| f(i as f64 / n as f64 * 2.0 * core::f64::consts::PI))
            .collect();
        // The sampling must be fine enough that consecutive points round to neighbours.
        let fine = points
            .windows(2)
            .all(|w| (0..4).all(|a| (w[0][a] - w[1][a]).abs() < 1.0));
        match self.rasterise(&points) {
            Some(path) if fine => self.draw_closed(&path),
            _ => false,
        }
    }

    /// Draws an open curve of about `length` voxels (a new contractible component) at a
    /// random place. Returns whether one was placed.
    pub fn add_curve(&mut self, length: usize) -> bool {
        let Some(start) = self.random_point(0.0) else {
            return false;
        };
        let points = self.walk(start, length);
        let mut path = Vec::new();
        for p in points {
            match self.voxel(p) {
                Some(v) if path.last() != Some(&v) => path.push(v),
                Some(_) => {}
                None => break,
            }
        }
        self.draw_open(&path, None, 3.min(length.max(1)))
    }

    /// Draws a circle of `radius` voxels in a random plane at a random place.
    pub fn add_circle(&mut self, radius: f64) -> bool {
        let d = self.dim();
        let Some(centre) = self.random_point(radius + 0.5) else {
            return false;
        };
        let basis = orthonormal(&mut self.rng, d, 2);
        self.closed_curve(
            |t| {
                let (c, s) = (libm::cos(t), libm::sin(t));
                core::array::from_fn(|a| centre[a] + radius * (c * basis[0][a] + s * basis[1][a]))
            },
            2.0 * core::f64::consts::PI * radius,
        )
    }

    /// Draws a trefoil knot of size `scale` (about 3 * `scale` voxels across) in a random
    /// 3D subspace (3D and 4D only; returns false in 2D).
    pub fn add_knot(&mut self, scale: f64) -> bool {
        let d = self.dim();
        if d < 3 {
            return false;
        }
        // The trefoil reaches 3 * scale from its centre.
        let Some(centre) = self.random_point(3.0 * scale + 0.5) else {
            return false;
        };
        let basis = orthonormal(&mut self.rng, d, 3);
        self.closed_curve(
            |t| {
                let x = libm::sin(t) + 2.0 * libm::sin(2.0 * t);
                let y = libm::cos(t) - 2.0 * libm::cos(2.0 * t);
                let z = -libm::sin(3.0 * t);
                core::array::from_fn(|a| {
                    centre[a] + scale * (x * basis[0][a] + y * basis[1][a] + z * basis[2][a])
                })
            },
            20.0 * scale,
        )
    }

    fn roots(&self) -> Vec<u32> {
        let mut roots: Vec<u32> = (1..self.parent.len() as u32)
            .filter(|&l| self.find(l) == l)
            .collect();
        roots.sort_unstable();
        roots
    }

    fn random_voxel_of(&mut self, root: u32) -> Option<usize> {
        let members: Vec<usize> = (1..self.voxels_of.len())
            .filter(|&l| self.find(l as u32) == root)
            .flat_map(|l| self.voxels_of[l].iter().copied())
            .collect();
        if members.is_empty() {
            return None;
        }
        Some(members[index_below(&mut self.rng, members.len())])
    }

    fn coords_f(&self, v: usize) -> [f64; 4] {
        self.image.coords(v).map(|c| c as f64)
    }

    /// Joins two random different components with a straight curve (b0 - 1). Returns
    /// false when fewer than two components exist or the curve would touch a third.
    pub fn add_bridge(&mut self) -> bool {
        let roots = self.roots();
        if roots.len() < 2 {
            return false;
        }
        let i = index_below(&mut self.rng, roots.len());
        let mut j = index_below(&mut self.rng, roots.len() - 1);
        if j >= i {
            j += 1;
        }
        let (a, b) = (roots[i], roots[j]);
        let (Some(pa), Some(pb)) = (self.random_voxel_of(a), self.random_voxel_of(b)) else {
            return false;
        };
        let (ca, cb) = (self.coords_f(pa), self.coords_f(pb));
        let dist = libm::sqrt((0..4).map(|k| (ca[k] - cb[k]) * (ca[k] - cb[k])).sum());
        let n = (dist / STEP).ceil().max(1.0) as usize;
        let points: Vec<[f64; 4]> = (0..=n)
            .map(|s| {
                let f = s as f64 / n as f64;
                core::array::from_fn(|k| ca[k] + f * (cb[k] - ca[k]))
            })
            .collect();
        let Some(path) = self.rasterise(&points) else {
            return false;
        };
        let mut t = self.begin();
        let mut k = 0;
        while k < path.len()
            && self.image.data()[path[k]] == 1
            && self.find(self.labels[path[k]]) == a
        {
            k += 1;
        }
        for &z in &path[k..] {
            if self.image.data()[z] == 1 {
                break;
            }
            let event = self.classify(z);
            match event {
                Event::Simple => self.add(&mut t, z, event),
                Event::Merge(x, y) if (x.min(y), x.max(y)) == (a.min(b), a.max(b)) => {
                    self.add(&mut t, z, event);
                    return true;
                }
                _ => break,
            }
        }
        self.rollback(t);
        false
    }

    /// Grows a curve of about `length` voxels out of a random existing object (no change
    /// in topology). Returns false when there is no object or no room.
    pub fn add_tentacle(&mut self, length: usize) -> bool {
        let roots = self.roots();
        if roots.is_empty() {
            return false;
        }
        let root = roots[index_below(&mut self.rng, roots.len())];
        let Some(start) = self.random_voxel_of(root) else {
            return false;
        };
        let points = self.walk(self.coords_f(start), length);
        let mut path = Vec::new();
        for p in points {
            match self.voxel(p) {
                Some(v) if path.last() != Some(&v) => path.push(v),
                Some(_) => {}
                None => break,
            }
        }
        self.draw_open(&path, Some(root), 2)
    }

    /// Places a thin shell (a 3D box whose voxels are `inside`, checked to have Betti
    /// numbers `expected`) at a random place and orientation, touching nothing.
    fn add_shell(
        &mut self,
        box_shape: [usize; 3],
        inside: impl Fn([f64; 3]) -> bool,
        expected: [u64; 3],
    ) -> bool {
        let d = self.dim();
        if d < 3 {
            return false;
        }
        let Ok(mut shell) = BinaryImage::zeros(&box_shape) else {
            return false;
        };
        let centre = box_shape.map(|n| (n as f64 - 1.0) / 2.0);
        for v in 0..shell.len() {
            let c = shell.coords(v);
            if inside(core::array::from_fn(|a| c[a] as f64 - centre[a])) {
                shell.data_mut()[v] = 1;
            }
        }
        if bettimill_homology::topology(&shell).betti != expected {
            return false;
        }
        // Axes of the image that the box's three axes map to; in 4D the remaining axis is
        // the one-voxel-thick direction.
        let mut axes: Vec<usize> = (0..d).collect();
        for i in (1..d).rev() {
            let j = index_below(&mut self.rng, i + 1);
            axes.swap(i, j);
        }
        let shape = self.image.shape().to_vec();
        let mut extent = [1usize; 4];
        for (k, &a) in axes.iter().take(3).enumerate() {
            extent[a] = box_shape[k];
        }
        let mut origin = [0usize; 4];
        for a in 0..d {
            if extent[a] + 2 * MARGIN > shape[a] {
                return false;
            }
            origin[a] = MARGIN + index_below(&mut self.rng, shape[a] - 2 * MARGIN - extent[a] + 1);
        }
        let mut targets = Vec::new();
        for v in 0..shell.len() {
            if shell.data()[v] == 0 {
                continue;
            }
            let c = shell.coords(v);
            let mut p = origin;
            for (k, &a) in axes.iter().take(3).enumerate() {
                p[a] += c[k];
            }
            targets.push(self.image.index(&p[..d]));
        }
        // Touching nothing: every target and all its neighbours are background.
        let data = self.image.data();
        let clear = targets.iter().all(|&z| {
            data[z] == 0
                && self
                    .neighbour_flat
                    .iter()
                    .all(|&f| data[(z as isize + f) as usize] == 0)
        });
        if !clear {
            return false;
        }
        let id = self.parent.len() as u32;
        self.parent.push(id);
        self.voxels_of.push(targets.clone());
        for &z in &targets {
            self.image.data_mut()[z] = 1;
            self.labels[z] = id;
        }
        for (k, &b) in expected.iter().enumerate() {
            self.betti[k] += b as i64;
        }
        true
    }

    /// Places a thin 2-sphere of `radius` voxels (3D and 4D only): b0 + 1, b2 + 1.
    pub fn add_sphere(&mut self, radius: f64) -> bool {
        let side = 2 * (libm::ceil(radius) as usize) + 3;
        self.add_shell(
            [side; 3],
            |p| {
                let r = libm::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
                r > radius - 1.5 && r <= radius
            },
            [1, 0, 1],
        )
    }

    /// Places a thin torus (core circle of radius `major`, tube of radius `minor`; 3D and
    /// 4D only): b0 + 1, b1 + 2, b2 + 1.
    pub fn add_torus(&mut self, major: f64, minor: f64) -> bool {
        let outer = 2 * (libm::ceil(major + minor) as usize) + 3;
        let tube = 2 * (libm::ceil(minor) as usize) + 3;
        self.add_shell(
            [outer, outer, tube],
            |p| {
                let q = libm::sqrt(p[0] * p[0] + p[1] * p[1]) - major;
                let r = libm::sqrt(q * q + p[2] * p[2]);
                r > minor - 1.5 && r <= minor
            },
            [1, 2, 1],
        )
    }
}

/// Draws a random scene of seeds: spheres, tori, circles, knots, curves, then bridges and
/// tentacles, with sizes scaled to the image's shortest axis. Deterministic per seed.
pub fn random_scene(shape: &[usize], spec: &SceneSpec, seed: u64) -> Result<Scene, DeformError> {
    let mut b = SeedBuilder::new(shape, seed)?;
    let side = *shape.iter().min().expect("validated shape") as f64;
    let mut placed = SceneSpec::default();
    type Attempt = fn(&mut SeedBuilder, f64) -> bool;
    type Counter = fn(&mut SceneSpec) -> &mut u32;
    let kinds: [(u32, Attempt, Counter); 7] = [
        (
            spec.spheres,
            |b, s| {
                let r = b.rng.gen_range((s / 10.0).max(3.0)..(s / 5.0).max(3.5));
                b.add_sphere(r)
            },
            |p| &mut p.spheres,
        ),
        (
            spec.tori,
            |b, s| {
                let major = b.rng.gen_range((s / 8.0).max(4.0)..(s / 5.0).max(4.5));
                let minor = b.rng.gen_range(2.0..(major / 2.0).max(2.5));
                b.add_torus(major, minor)
            },
            |p| &mut p.tori,
        ),
        (
            spec.circles,
            |b, s| {
                let r = b.rng.gen_range((s / 12.0).max(3.0)..(s / 5.0).max(3.5));
                b.add_circle(r)
            },
            |p| &mut p.circles,
        ),
        (
            spec.knots,
            |b, s| {
                let k = b.rng.gen_range((s / 16.0).max(2.0)..(s / 10.0).max(2.5));
                b.add_knot(k)
            },
            |p| &mut p.knots,
        ),
        (
            spec.curves,
            |b, s| {
                let lo = (s / 3.0) as usize;
                let n = lo + index_below(&mut b.rng, (s as usize).max(2) - lo);
                b.add_curve(n)
            },
            |p| &mut p.curves,
        ),
        (spec.bridges, |b, _| b.add_bridge(), |p| &mut p.bridges),
        (
            spec.tentacles,
            |b, s| {
                let lo = (s / 6.0) as usize + 2;
                let n = lo + index_below(&mut b.rng, (s / 2.0) as usize + 3 - lo);
                b.add_tentacle(n)
            },
            |p| &mut p.tentacles,
        ),
    ];
    for (wanted, attempt, counter) in kinds {
        for _ in 0..wanted {
            if (0..ATTEMPTS).any(|_| attempt(&mut b, side)) {
                *counter(&mut placed) += 1;
            }
        }
    }
    let (image, betti) = b.finish();
    Ok(Scene {
        image,
        betti,
        placed,
    })
}
