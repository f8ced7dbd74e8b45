//! `bettimill deform`: topology-preserving deformation of a user's own `.npy` image.

use crate::commands::ExitStatus;
use anyhow::Context;
use bettimill_deform::{DeformSettings, Method};
use clap::{Args, ValueEnum};
use std::path::PathBuf;

/// The deformation to apply.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum MethodArg {
    /// Hypervolume-preserving moves of simple boundary voxels (the count stays exact).
    Moves,
    /// Noise-modulated topology-preserving dilation.
    Dilate,
    /// Noise-modulated topology-preserving erosion.
    Erode,
    /// Thin protrusions grown along persistent random directions (`--count` of them,
    /// `--steps` voxels long).
    Tentacles,
    /// Random-walk bodies (`--count` walkers of `--steps` steps).
    Walk,
    /// Narrow necks: `--count` slabs across the image's foreground, each eroded for
    /// `--steps` iterations inside the slab.
    Pinch,
    /// 2D only: the paper's hit-or-miss thickening (thinning of the background), each flip
    /// guarded by the simple-point test; `--steps` counts rounds; no noise, no seed.
    HitOrMiss,
}

/// Arguments of `bettimill deform`.
#[derive(Args, Debug)]
pub struct DeformArgs {
    /// Input image: .npy (also .npy.gz, .npy.zst, or - for standard input) of bool or
    /// integer dtype with 2 to 4 axes (non-zero = foreground).
    image: PathBuf,
    /// Output .npy (same shape and dtype as the input, values 0 and 1).
    #[arg(long)]
    out: PathBuf,
    /// The deformation.
    #[arg(long, value_enum)]
    method: MethodArg,
    /// Moves to apply, or morphology iterations.
    #[arg(long)]
    steps: u32,
    /// Seed of the noise and of every random choice.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Improved Noise frequency in cycles per voxel, in (0, 1] (the manifest's default).
    #[arg(long, default_value_t = bettimill_deform::DEFAULT_NOISE_FREQUENCY)]
    noise_frequency: f64,
    /// Fractal octaves of the noise, 1 to 24 (the manifest's default).
    #[arg(long, default_value_t = bettimill_deform::DEFAULT_OCTAVES)]
    octaves: u32,
    /// Moves: the farthest (Chebyshev) distance a voxel may travel, 1 to 8 (the manifest's
    /// default).
    #[arg(long, default_value_t = bettimill_deform::DEFAULT_MAX_DISTANCE)]
    max_distance: u32,
    /// Dilate/erode/pinch: the share of the frontier that may flip per iteration, in (0, 1]
    /// (the manifest's default); 1 is plain topology-preserving morphology.
    #[arg(long, default_value_t = bettimill_deform::DEFAULT_GROWTH_PROBABILITY)]
    growth_probability: f64,
    /// Tentacles, walk and pinch: how many.
    #[arg(long, default_value_t = bettimill_deform::DEFAULT_COUNT)]
    count: u32,
    /// Refuse input values other than 0 and 1.
    #[arg(long)]
    strict: bool,
    /// Print a JSON report on stdout.
    #[arg(long)]
    json: bool,
}

/// Runs `bettimill deform`.
pub fn run(args: &DeformArgs) -> anyhow::Result<ExitStatus> {
    crate::stats::refuse_inside_dataset(&args.out, "--out")?;
    let input = crate::image::read_image(&args.image, args.strict)?;
    let method = match args.method {
        MethodArg::Moves => Method::Moves,
        MethodArg::Dilate => Method::Dilate,
        MethodArg::Erode => Method::Erode,
        MethodArg::Tentacles => Method::Tentacles,
        MethodArg::Walk => Method::Walk,
        MethodArg::Pinch => Method::Pinch,
        MethodArg::HitOrMiss => Method::Dilate,
    };
    let settings = DeformSettings {
        method,
        steps: args.steps,
        noise_frequency: args.noise_frequency,
        octaves: args.octaves,
        max_distance: args.max_distance,
        growth_probability: args.growth_probability,
        count: args.count,
    };
    let mut image = input.image.clone();
    let before = bettimill_homology::try_topology(&image)?;
    let report = match args.method {
        MethodArg::HitOrMiss => bettimill_deform::hitmiss::thicken_2d(&mut image, args.steps)?,
        _ => bettimill_deform::deform(&mut image, &settings, args.seed)?,
    };
    // The deformation is topology-preserving by construction; the check is cheap next to it
    // and keeps the promise visible to the user.
    let after = bettimill_homology::try_topology(&image)?;
    anyhow::ensure!(
        before == after,
        "internal error: the deformation changed the Betti numbers from {:?} to {:?}; nothing written",
        before.betti,
        after.betti
    );
    let bytes = bettimill_grid::npy::write_bytes(&image, input.dtype);
    std::fs::write(&args.out, bytes)
        .with_context(|| format!("cannot write {}", args.out.display()))?;
    if args.json {
        let value = serde_json::json!({
            "betti": after.betti,
            "euler": after.euler,
            "applied": report.applied,
            "rejected": report.rejected,
            "iterations": report.iterations,
            "hypervolume_before": report.foreground_before,
            "hypervolume_after": report.foreground_after,
        });
        outln!("{value}");
    } else {
        outln!(
            "applied {} of {} steps; hypervolume {} -> {}; betti {:?} unchanged",
            report.applied,
            args.steps,
            report.foreground_before,
            report.foreground_after,
            after.betti
        );
    }
    Ok(ExitStatus::Success)
}
