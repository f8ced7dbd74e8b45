//! Pictures and summaries of datasets for people: PNG previews of samples (2D as is, 3D as
//! slices and a projection, 4D as rows of 3D slices, each cropped to the object and cut
//! where a hole shows), contact sheets, and statistics with a histogram chart.
//!
//! Everything here is a pure function of bytes and images: the CLI reads the files and
//! writes the files. Equal inputs give equal PNG bytes (see [`Canvas::to_png`]).
//!
//! - [`font`]: the bundled font (DejaVu Sans Mono) for captions.
//! - [`canvas`]: the RGB drawing surface.
//! - [`focus`]: the crop box and the slice that shows the topology.
//! - [`render`]: layouts of one sample and of contact sheets.
//! - [`samples`]: labels and arrays read back from shard bytes.
//! - [`stats`]: counts, regeneration rates, the hypervolume histogram and the chart.
//! - [`viewer`]: the self-contained HTML viewer of one sample and its downscaled copies.

pub mod canvas;
pub mod focus;
pub mod font;
pub mod render;
pub mod samples;
pub mod stats;
pub mod viewer;

pub use canvas::Canvas;
pub use focus::guess_mode;
pub use render::{caption, contact_sheet, label_mode, render_sample, short_caption, Subject};
pub use samples::{
    keys_in_tar, labels_in_stream, labels_in_tar, samples_in_stream, samples_in_tar, SampleView,
};
pub use stats::{plot, BuildTime, Preservation, Stats};
pub use viewer::{viewer_html, ViewerImage};

/// Why a preview or statistic could not be made.
#[derive(Debug, thiserror::Error)]
pub enum PreviewError {
    /// A shard could not be read.
    #[error(transparent)]
    Shard(#[from] bettimill_shard::ShardError),
    /// An array member is not a valid `.npy`.
    #[error("{what} is not a usable image: {source}")]
    Npy {
        /// The member.
        what: String,
        /// Why.
        source: bettimill_grid::npy::NpyError,
    },
    /// A label member is not a bettimill label.
    #[error("{key}.json is not a bettimill label: {source}")]
    Label {
        /// The sample key.
        key: String,
        /// Why.
        source: serde_json::Error,
    },
    /// A sample lacks a member.
    #[error("sample {key} has no {field} member")]
    Missing {
        /// The sample key.
        key: String,
        /// `json` or `npy`.
        field: &'static str,
    },
    /// The picture would be too large to draw.
    #[error("a {width}x{height} picture is too large to draw (at most {max} pixels)", max = canvas::MAX_PIXELS)]
    TooLarge {
        /// Requested width.
        width: usize,
        /// Requested height.
        height: usize,
    },
    /// The PNG encoder failed.
    #[error("cannot encode the PNG: {0}")]
    Png(#[from] png::EncodingError),
    /// The chart could not be drawn.
    #[error("cannot draw the chart: {0}")]
    Chart(String),
    /// An image too large for the viewer page.
    #[error("{name} has {voxels} voxels; the viewer embeds at most {max}: view a downscaled copy or use --out", max = viewer::MAX_VOXELS)]
    TooManyVoxels {
        /// The image.
        name: String,
        /// Its voxels.
        voxels: usize,
    },
    /// A slice's Betti numbers could not be computed.
    #[error(transparent)]
    Topology(#[from] bettimill_homology::TopologyError),
    /// Nothing to draw.
    #[error("no samples to draw")]
    Empty,
}
