//! The label stored as `KEY.json` in every sample.

use bettimill_types::DeformSettings;
use serde::{Deserialize, Serialize};

/// The label stored as `KEY.json`. Field order is fixed by this struct, and the
/// construction record is a JSON value with sorted keys, so equal labels are equal bytes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Label {
    /// The WebDataset key.
    pub key: String,
    /// Betti numbers over Z/2, computed from the stored voxels.
    pub betti: Vec<u64>,
    /// Betti numbers over Q when they differ from the Z/2 ones (non-orientable pieces).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub betti_rational: Option<Vec<u64>>,
    /// The coefficient field of `betti`.
    pub field: String,
    /// Euler characteristic.
    pub euler: i64,
    /// Foreground voxel count.
    pub hypervolume: u64,
    /// Number of objects placed by the construction.
    pub components: u64,
    /// Image shape.
    pub shape: Vec<usize>,
    /// Number of axes.
    pub dim: usize,
    /// `embed` or `carve`.
    pub mode: String,
    /// Construction family label.
    pub family: String,
    /// Knot or link type ("none" when there is none): a label Betti numbers cannot see.
    pub knot_type: String,
    /// Index of the sample's stratum in the plan (also stored as `KEY.cls`). Written as
    /// `class_index` in the JSON, the name datasets have always carried; in code it is the
    /// stratum, not the manifest class (`Stratum::manifest_class`).
    #[serde(rename = "class_index")]
    pub stratum: usize,
    /// Human-readable stratum name.
    pub class_label: String,
    /// The sample's seed, 64 hex digits.
    pub seed: String,
    /// Which attempt (from 0) produced the sample; > 0 means earlier attempts were rejected.
    pub attempt: u32,
    /// The manifest's canonical hash.
    pub manifest_hash: String,
    /// bettimill version.
    pub tool_version: String,
    /// How the sample was built.
    pub construction: serde_json::Value,
    /// The deformation steps applied to the topological phase, in order, each with the
    /// settings this sample drew (empty when the manifest asks for none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub deform: Vec<DeformSettings>,
    /// The gap width growth kept, as this sample drew it from the manifest's `clearance`
    /// (0 when hypervolume targeting could only reach the bin without it); absent when
    /// the manifest sets none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clearance: Option<u32>,
    /// How many dilations of the topological phase the sample was checked to survive with
    /// its Betti numbers unchanged, as the manifest's `survives_dilations` asks (0 when the
    /// last attempts, which skip the check so that every stratum builds, made it); absent
    /// when the manifest asks for none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub survives_dilations: Option<u32>,
    /// The gap, in background voxels, that growth kept between the components of the
    /// topological phase: the construction's `gap_voxels` (drawn per sample in a scene),
    /// 2 or 0 where hypervolume targeting could reach the bin only with the narrowest gap
    /// or without one; absent when the phase has one component.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub separation: Option<u32>,
    /// The foreground voxel bin `[lo, hi]` the sample was brought into, if binned.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hypervolume_bin: Option<(u64, u64)>,
    /// Downscaled copies (stored as `KEY.rSIDE.npy`), each with its own computed labels.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub resolutions: Vec<ResolutionLabel>,
}

/// How a downscaled copy is pooled from the full-resolution voxels: which phase wins a
/// block that holds both.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Pooling {
    /// A coarse voxel is foreground when any of its fine voxels is (max pooling). Every
    /// copy written before bettimill 0.2.0 was pooled this way, so a label without the
    /// field reads as this.
    #[default]
    ForegroundAny,
    /// A coarse voxel is background when any of its fine voxels is (min pooling): the
    /// cavities of carve mode are never filled in (but thin foreground between them
    /// closes).
    BackgroundAny,
}

impl Pooling {
    /// The label's spelling (`foreground_any`, `background_any`).
    pub fn name(self) -> &'static str {
        match self {
            Pooling::ForegroundAny => "foreground_any",
            Pooling::BackgroundAny => "background_any",
        }
    }
}

/// The label of one downscaled copy.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ResolutionLabel {
    /// Side length of the copy.
    pub side: u32,
    /// How the copy was pooled.
    #[serde(default)]
    pub pooling: Pooling,
    /// Its Betti numbers over Z/2, computed from its voxels.
    pub betti: Vec<u64>,
    /// Its Euler characteristic.
    pub euler: i64,
    /// Its foreground voxel count.
    pub hypervolume: u64,
    /// Whether downscaling kept every Betti number.
    pub preserved: bool,
}

impl Label {
    /// Parses a `KEY.json` member.
    pub fn from_json(bytes: &[u8]) -> Result<Label, serde_json::Error> {
        serde_json::from_slice(bytes)
    }

    /// The stored Betti numbers of the copy of side `side`: the label's own for the full
    /// resolution, a [`ResolutionLabel`]'s for a downscaled copy. `None` when the label has
    /// no copy of that side.
    pub fn betti_at(&self, side: Option<u32>) -> Option<&[u64]> {
        match side {
            None => Some(&self.betti),
            Some(side) => self
                .resolutions
                .iter()
                .find(|r| r.side == side)
                .map(|r| r.betti.as_slice()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Pooling;

    #[test]
    fn pooling_names_are_the_label_spelling() {
        for pooling in [Pooling::ForegroundAny, Pooling::BackgroundAny] {
            assert_eq!(
                serde_json::to_value(pooling).unwrap(),
                serde_json::Value::from(pooling.name())
            );
        }
    }
}
