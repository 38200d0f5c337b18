//! Point references: the radiosity B = E + ρ H at given surface points,
//! path traced with the reference's own estimator, with a standard error
//! per point. The yardstick for the bias of a solution, which pixel noise
//! does not hide.
//!
//! Owns: [`ProbePoint`] (a point and the normal of the side it looks
//! from), [`probe_radiosity`], and [`random_points`] (points spread over
//! the scene by area).
//!
//! Invariants: a point must lie on a patch (within a small tolerance) and
//! face the way that patch does, else it is an error naming the point;
//! path `s` of point `k` draws from `stream(seed ^ TAG, k << 32 | s)`,
//! so values are bit-identical for any thread count. The standard error
//! is honest: it comes from independent replicas of the whole estimate.

use std::f64::consts::PI;

use glam::{DVec2, DVec3};
use rand::Rng;
use rayon::prelude::*;

use super::tracer::{SurfaceHit, Tracer};
use crate::error::{Error, Result};
use crate::sampling::{point_in_polygon, stream};
use crate::scene::Scene;
use crate::util::progress::Progress;

/// Mixed into the seed: probes and images never share a stream.
const PROBE_TAG: u64 = 0x7072_6f62_6570_7473;

/// How far off its surface a point may lie, as a fraction of the scene
/// diagonal.
const ON_SURFACE: f64 = 1e-4;

/// A surface point and the unit normal of the side whose radiosity is
/// wanted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbePoint {
    /// Position (world space).
    pub position: DVec3,
    /// Unit normal of the radiating side.
    pub normal: DVec3,
}

/// How many paths each point gets, and their seed.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeSettings {
    /// Paths per point; at least 2 (the standard error needs two).
    pub samples: u32,
    /// Seed of every path.
    pub seed: u64,
    /// Largest number of reflections of a path (`None`: unlimited).
    pub max_bounces: Option<u32>,
}

impl ProbeSettings {
    /// Checks the sample count. The error names the command-line option.
    pub fn validate(&self) -> Result<()> {
        if self.samples < 2 {
            return Err(Error::Setting(
                "--spp must be at least 2 for the standard error".into(),
            ));
        }
        Ok(())
    }
}

/// The radiosity at one point and its standard error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeValue {
    /// The point as given.
    pub point: ProbePoint,
    /// The patch it lies on.
    pub patch: u32,
    /// B = E + ρ H, W/m² per channel.
    pub radiosity: DVec3,
    /// Standard error of `radiosity`, per channel.
    pub standard_error: DVec3,
}

/// Path traces the radiosity at each of `points`.
pub fn probe_radiosity(
    scene: &Scene,
    points: &[ProbePoint],
    settings: &ProbeSettings,
    progress: &Progress,
) -> Result<Vec<ProbeValue>> {
    settings.validate()?;
    let tracer = Tracer::new(scene, settings.max_bounces)?;
    let hits: Vec<SurfaceHit> = points
        .iter()
        .enumerate()
        .map(|(k, p)| locate(scene, &tracer, k, p))
        .collect::<Result<_>>()?;
    let seed = settings.seed ^ PROBE_TAG;
    let phase = progress.phase("probe", points.len() as u64);
    let values = points
        .par_iter()
        .zip(hits)
        .enumerate()
        .map(|(k, (p, hit))| {
            let value = estimate(&tracer, &hit, settings.samples, seed, k as u64);
            phase.inc(1);
            ProbeValue {
                point: *p,
                patch: hit.patch_index,
                radiosity: value.0,
                standard_error: value.1,
            }
        })
        .collect();
    Ok(values)
}

/// Independent replicas of a point's estimate: its standard error comes
/// from the spread of their means.
const REPLICAS: u32 = 16;

/// The radiosity at `hit` (point `k`) from `samples` paths, and its
/// standard error. The first bounce's directions are stratified: each of
/// the [`REPLICAS`] replicas jitters its own grid of strata over the unit
/// square (which way the first bounce goes is most of the variance when
/// the light arrives through a small opening), so the replicas' means are
/// independent and identically distributed, and the standard error is
/// their standard deviation over √replicas.
fn estimate(tracer: &Tracer, hit: &SurfaceHit, samples: u32, seed: u64, k: u64) -> (DVec3, DVec3) {
    let per = samples.div_ceil(REPLICAS).max(1);
    let side = f64::from(per).sqrt().ceil() as u32;
    let mut means = Vec::with_capacity(REPLICAS as usize);
    for r in 0..REPLICAS {
        let mut sum = DVec3::ZERO;
        for s in 0..per {
            let mut rng = stream(seed, k << 32 | u64::from(r * per + s));
            // Stratum s of a side × side grid (the last row partly used).
            let (i, j) = (s % side, s / side);
            let rows = per.div_ceil(side);
            let u = DVec2::new(
                (f64::from(i) + rng.random::<f64>()) / f64::from(side),
                (f64::from(j) + rng.random::<f64>()) / f64::from(rows),
            );
            let at = SurfaceHit {
                point: hit.point,
                patch: hit.patch,
                patch_index: hit.patch_index,
            };
            sum += PI * tracer.leaving_from(at, Some(u), &mut rng);
        }
        means.push(sum / f64::from(per));
    }
    let n = f64::from(REPLICAS);
    let mean = means.iter().sum::<DVec3>() / n;
    let var = means
        .iter()
        .map(|m| (*m - mean) * (*m - mean))
        .sum::<DVec3>()
        / (n - 1.0);
    (mean, (var / n).map(f64::sqrt))
}

/// The radiating surface under point `k`: a ray from just in front of it
/// back along its normal must meet, within [`ON_SURFACE`], a patch that
/// faces the same way.
fn locate<'a>(
    scene: &Scene,
    tracer: &Tracer<'a>,
    k: usize,
    p: &ProbePoint,
) -> Result<SurfaceHit<'a>> {
    let fail = |why: &str| {
        Error::Setting(format!(
            "probe point {k} at ({}, {}, {}): {why}",
            p.position.x, p.position.y, p.position.z
        ))
    };
    let n = p.normal.normalize_or_zero();
    if !(p.position.is_finite() && n.length_squared() > 0.5) {
        return Err(fail("needs a finite position and a non-zero normal"));
    }
    let reach = ON_SURFACE * scene.diagonal();
    let from = p.position + reach * n;
    match tracer.trace(from, -n) {
        Some(hit)
            if hit.point.distance(p.position) <= 2.0 * reach && hit.patch.normal.dot(n) > 0.5 =>
        {
            Ok(hit)
        }
        _ => Err(fail("no surface facing that way lies there")),
    }
}

/// `count` points spread over the non-emitting patches by area (each
/// point's patch chosen from its own stratum of the area, a uniform point
/// inside it), each with its patch's normal. Deterministic for a seed.
pub fn random_points(scene: &Scene, count: usize, seed: u64) -> Vec<ProbePoint> {
    let patches: Vec<usize> = (0..scene.patches.len())
        .filter(|&p| !scene.patches[p].is_emitter())
        .collect();
    let total: f64 = patches.iter().map(|&p| scene.patches[p].area).sum();
    if patches.is_empty() || !(total > 0.0) {
        return Vec::new();
    }
    let mut cumulative = Vec::with_capacity(patches.len());
    let mut acc = 0.0;
    for &p in &patches {
        acc += scene.patches[p].area / total;
        cumulative.push(acc);
    }
    let mut rng = stream(seed ^ PROBE_TAG, u64::MAX);
    (0..count)
        .map(|i| {
            // One stratum of the area fraction per point picks the patch;
            // fresh numbers place the point in it.
            let t = (i as f64 + rng.random::<f64>()) / count as f64;
            let k = cumulative
                .partition_point(|&c| c <= t)
                .min(patches.len() - 1);
            let patch = &scene.patches[patches[k]];
            let u = DVec2::new(rng.random(), rng.random());
            ProbePoint {
                position: point_in_polygon(patch.vertices(), u),
                normal: patch.normal,
            }
        })
        .collect()
}
