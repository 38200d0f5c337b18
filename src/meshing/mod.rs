//! The output mesh of a hierarchical solution, in one of three modes, with
//! every vertex value computed at the vertex.
//!
//! Owns: [`MeshMode`], [`MeshSettings`], [`MeshStats`], [`build_mesh`] and
//! the steps it runs, each in its own file:
//!
//! 1. `points.rs`: the points and constraints of each patch, by mode:
//!    - `uniform`: a regular grid at one spacing for the whole scene (chosen
//!      for a target vertex count), with points at that spacing along the
//!      patch edges;
//!    - `quadtree`: the corners of the hierarchy's leaves;
//!    - `discontinuity`: the leaf corners, with the discontinuity segments
//!      as constraint edges (corners a hair off a segment snapped onto it).
//! 2. [`triangulate`]: spade's constrained Delaunay triangulation per
//!    patch, vertices shared bit for bit along patch edges. In
//!    `discontinuity`, the patches along a contact line then exchange their
//!    vertices on it and are triangulated again (`contact.rs`).
//! 3. Each vertex's radiosity by a final gather at the vertex
//!    ([`point_gather::PointEvaluator`], built on
//!    [`point_gather::point_light`]) from the leaf that holds it, the
//!    emitters' direct light gathered at the vertex itself (exact form
//!    factor and its own rays) for up to
//!    [`point_gather::MAX_DIRECT_EMITTERS`] emitter patches; an emitter from
//!    which no link of the solution brings light to any part of the vertex's
//!    patch is first checked with a few rays
//!    ([`point_gather::dark_emitters`]). Values are cached by patch and
//!    exact position, so each vertex is evaluated once.
//! 4. `discontinuity` only, output adaptivity (`adapt.rs`): a triangle whose
//!    centroid's point value differs from the interpolation of its vertices
//!    by more than the tolerance gets its centroid as a new point; the
//!    patches are triangulated again and the new vertices evaluated, for a
//!    few passes within a vertex budget.
//! 5. The output mesh, patch by patch; `discontinuity` only: a vertex on a
//!    contact line (a D0 discontinuity, where the radiosity jumps) becomes
//!    one vertex per side of the line, each evaluated just off the line on
//!    its own side (`contact.rs`). The copies share their position, so the
//!    surface stays closed.
//!
//! [`leaf`] is the plain alternative: each leaf triangulated on its own.
//! [`seams`] reads any output mesh back: the report's estimate of its
//! vertex error.
//!
//! Invariants: the mesh passes [`OutputMesh::validate`]; along patch edges
//! neighbouring patches have the same vertex positions (no cracks, no
//! T-vertices); the result depends only on the inputs and the seed, not on
//! the thread count (evaluations run in parallel, each into its own slot,
//! with rays seeded per leaf and source).

pub mod leaf;
pub mod point_gather;
pub mod seams;
pub mod triangulate;

mod adapt;
mod contact;
mod points;

use std::collections::{HashMap, HashSet};
use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use crate::discontinuity::Segment;
use crate::error::Result;
use crate::hierarchical::{HierarchicalSolution, scene_scales};
use crate::mesh::OutputMesh;
use crate::meshing::adapt::Adaptivity;
use crate::meshing::point_gather::{LinkRays, PointEvaluator, PointLight};
use crate::meshing::triangulate::{
    PatchInput, PatchTriangulation, TriangulateOptions, triangulate_patches,
};
use crate::scene::Scene;
use crate::util::geometry::{PositionKey, position_key};
use crate::util::progress::Progress;
use crate::util::tolerance;
use crate::visibility::TriangleBvh;

/// Rounds of the contact-line vertex exchange at most, before the
/// triangulation is kept as it is.
const MAX_CONTACT_EXCHANGES: usize = 3;

/// Where the output mesh puts its vertices.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "kebab-case")]
pub enum MeshMode {
    /// A regular grid, blind to the lighting.
    Uniform,
    /// The corners of the hierarchy's leaves.
    Quadtree,
    /// The leaf corners plus the discontinuity segments as constraint
    /// edges, with output adaptivity and split vertices on contact lines.
    Discontinuity,
}

impl MeshMode {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            MeshMode::Uniform => "uniform",
            MeshMode::Quadtree => "quadtree",
            MeshMode::Discontinuity => "discontinuity",
        }
    }
}

/// Knobs of [`build_mesh`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct MeshSettings {
    /// Where the vertices go.
    pub mode: MeshMode,
    /// `uniform`: the number of vertices aimed at (`None`: as many as the
    /// hierarchy has leaves, the size of the `quadtree` mesh).
    pub uniform_vertices: Option<usize>,
    /// Output adaptivity: a centroid is added when its value and the
    /// interpolated one differ by more than this fraction of their mean
    /// (plus 1 % of the scene's mean emitted exitance, so that noise in the
    /// dark is not chased). 0 turns adaptivity off.
    pub adapt_tol: f64,
    /// Most vertices adaptivity may add, as a fraction of the initial
    /// vertex count.
    pub adapt_budget: f64,
    /// Adaptivity passes at most.
    pub adapt_passes: usize,
    /// Seed of the vertices' visibility rays.
    pub seed: u64,
    /// The run's time budget ends here (`--time-budget`): points evaluated
    /// after it take their leaf's value (see
    /// [`PointEvaluator::leaf_value`]) and adaptivity stops.
    #[serde(skip)]
    pub deadline: Option<Instant>,
}

/// Bytes the output mesh takes per vertex through its build, evaluation
/// and render: about 0.9 KB measured (peak memory of the Cornell box at
/// 20,000 and 200,000 `uniform` vertices), rounded up.
pub const OUTPUT_VERTEX_BYTES: u64 = 1024;

impl MeshSettings {
    /// For `uniform` with a vertex count given (`--uniform-vertices`):
    /// the points its grid makes on `scene`, counted without allocating,
    /// must fit `memory_budget` at [`OUTPUT_VERTEX_BYTES`] each; the error
    /// names the flag and the memory it would need. (Without a count, the
    /// mesh has as many vertices as the hierarchy has leaves, which the
    /// solver's budgets bound.)
    pub fn check_budget(&self, scene: &Scene, memory_budget: u64) -> Result<()> {
        let (MeshMode::Uniform, Some(target)) = (self.mode, self.uniform_vertices) else {
            return Ok(());
        };
        let points = points::uniform_point_bound(scene, target);
        let need = points.saturating_mul(OUTPUT_VERTEX_BYTES);
        if need > memory_budget {
            use crate::classic::uniform::human_bytes;
            return Err(crate::error::Error::Setting(format!(
                "--uniform-vertices {target} puts up to {points} vertices on the scene's patches, \
                 which need {}, over the memory budget of {} (ask for fewer vertices or raise \
                 --memory-budget)",
                human_bytes(need),
                human_bytes(memory_budget)
            )));
        }
        Ok(())
    }

    /// Checks the adaptivity tolerance (zero or positive). The error names
    /// the command-line option.
    pub fn validate(&self) -> Result<()> {
        if !(self.adapt_tol >= 0.0 && self.adapt_tol.is_finite()) {
            return Err(crate::error::Error::Setting(
                "--adapt-tol must be zero or positive".into(),
            ));
        }
        Ok(())
    }
}

impl Default for MeshSettings {
    /// Discontinuity mode, 5 % tolerance, at most 50 % more vertices in at
    /// most 3 passes.
    fn default() -> Self {
        MeshSettings {
            mode: MeshMode::Discontinuity,
            uniform_vertices: None,
            adapt_tol: 0.05,
            adapt_budget: 0.5,
            adapt_passes: 3,
            seed: 0,
            deadline: None,
        }
    }
}

/// What [`build_mesh`] did.
#[derive(
    Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
pub struct MeshStats {
    /// [`MeshMode::name`] of the mode used.
    pub mode: String,
    /// Discontinuity segments given as constraints.
    pub segments: usize,
    /// Mesh edges on those segments.
    pub constrained_edges: usize,
    /// Vertices of the first triangulation.
    pub initial_vertices: usize,
    /// Vertices added by output adaptivity.
    pub adaptive_vertices: usize,
    /// Extra vertex copies made on contact lines.
    pub split_vertices: usize,
    /// Emitter patches whose light is gathered at each vertex (0: through
    /// the links, beyond `MAX_DIRECT_EMITTERS`).
    pub direct_emitters: usize,
    /// Point evaluations (vertices, copies and centroid checks).
    pub evaluations: usize,
    /// Of those, how many took their leaf's value because the time budget
    /// was spent.
    pub late_evaluations: usize,
    /// Wall time in [`triangulate_patches`], over all passes.
    pub triangulate_seconds: f64,
    /// Wall time evaluating vertex and centroid values and assembling the
    /// mesh.
    pub evaluate_seconds: f64,
}

/// The output mesh of `solution` in the mode of `settings`. `segments` are
/// the discontinuity segments by patch (used by `discontinuity` only).
pub fn build_mesh(
    scene: &Scene,
    bvh: &TriangleBvh,
    solution: &HierarchicalSolution,
    segments: &[Vec<Segment>],
    settings: &MeshSettings,
    progress: &Progress,
) -> Result<(OutputMesh, MeshStats)> {
    let np = scene.patches.len();
    let mut stats = MeshStats {
        mode: settings.mode.name().into(),
        ..MeshStats::default()
    };
    let inputs = points::patch_inputs(scene, &solution.hierarchy, segments, settings, &mut stats);
    let contacts = match settings.mode {
        MeshMode::Discontinuity => contact::contact_segments(segments, np),
        MeshMode::Uniform | MeshMode::Quadtree => vec![Vec::new(); np],
    };
    let points = PointEvaluator::new(scene, bvh, solution, settings.seed).until(settings.deadline);
    stats.direct_emitters = points.direct_emitters().len();
    let (exitance, _, _) = scene_scales(scene);
    let mesher = Mesher {
        scene,
        progress: *progress,
        points,
        settings,
        contacts,
        coincident: tolerance::COINCIDENT * scene.diagonal(),
        adaptivity: Adaptivity {
            tol: settings.adapt_tol,
            exitance,
            min_area: solution.thresholds.min_area,
        },
    };
    let (tris, cache) = mesher.triangulate_and_evaluate(inputs, &mut stats)?;
    let mesh = mesher.assemble(&tris, &cache, &mut stats);
    stats.late_evaluations = mesher.points.late_count();
    Ok((mesh, stats))
}

/// What the steps of [`build_mesh`] after the patch inputs share.
struct Mesher<'a> {
    scene: &'a Scene,
    progress: Progress,
    points: PointEvaluator<'a>,
    settings: &'a MeshSettings,
    /// The contact segments by patch (none outside `discontinuity`).
    contacts: Vec<Vec<Segment>>,
    /// Points this close are one point on a contact line.
    coincident: f64,
    adaptivity: Adaptivity,
}

impl Mesher<'_> {
    /// Steps 2–4: triangulates `inputs` and evaluates the new vertices,
    /// again after each contact-line exchange (at most
    /// [`MAX_CONTACT_EXCHANGES`]) and each adaptivity pass that added
    /// points. Returns the last triangulation and the values of its
    /// vertices (among others).
    fn triangulate_and_evaluate(
        &self,
        mut inputs: Vec<PatchInput>,
        stats: &mut MeshStats,
    ) -> Result<(Vec<PatchTriangulation>, ValueCache)> {
        let settings = self.settings;
        let mut cache = ValueCache(HashMap::new(), self.progress);
        let mut added = 0;
        let mut pass = 0;
        let mut exchanges = 0;
        let tris = loop {
            let t = Instant::now();
            let tris = triangulate_patches(self.scene, &inputs, &TriangulateOptions::default())?;
            stats.triangulate_seconds += t.elapsed().as_secs_f64();
            // A contact line lies inside one patch and along another's edge:
            // each needs the other's vertices there (no T-vertices).
            if exchanges < MAX_CONTACT_EXCHANGES {
                let missing =
                    contact::contact_points(self.scene, &tris, &self.contacts, self.coincident);
                if missing.iter().any(|m| !m.is_empty()) {
                    for (input, m) in inputs.iter_mut().zip(missing) {
                        input.points.extend(m);
                    }
                    exchanges += 1;
                    continue;
                }
            }

            let t = Instant::now();
            stats.evaluations += cache.evaluate_new(&tris, &self.points);
            if pass == 0 {
                stats.initial_vertices = tris.iter().map(|t| t.positions.len()).sum();
            }
            let budget = (settings.adapt_budget * stats.initial_vertices as f64) as usize;
            let adapt = settings.mode == MeshMode::Discontinuity
                && settings.adapt_tol > 0.0
                && !self.points.late()
                && pass < settings.adapt_passes
                && added < budget;
            if !adapt {
                stats.evaluate_seconds += t.elapsed().as_secs_f64();
                break tris;
            }

            let centroids = self.adaptivity.centroids_to_add(
                &tris,
                &mut cache,
                &self.points,
                budget - added,
                stats,
            );
            stats.evaluate_seconds += t.elapsed().as_secs_f64();
            if centroids.is_empty() {
                break tris;
            }
            for &(p, x) in &centroids {
                inputs[p].points.push(x);
            }
            added += centroids.len();
            pass += 1;
        };
        stats.adaptive_vertices = added;
        Ok((tris, cache))
    }

    /// Step 5: the output mesh of `tris`, patch by patch, with each vertex
    /// on a contact line split into one copy per side.
    fn assemble(
        &self,
        tris: &[PatchTriangulation],
        cache: &ValueCache,
        stats: &mut MeshStats,
    ) -> OutputMesh {
        let t = Instant::now();
        let nudge = contact::NUDGE * self.scene.diagonal();
        let mut mesh = OutputMesh::default();
        for (p, tri) in tris.iter().enumerate() {
            let base = mesh.positions.len() as u32;
            let normal = self.scene.patches[p].normal.as_vec3();
            for &x in &tri.positions {
                mesh.positions.push(x.as_vec3());
                mesh.normals.push(normal);
                mesh.patch.push(p as u32);
                let light = cache.light(p, x);
                mesh.radiosity.push(light.radiosity.as_vec3());
                mesh.irradiance.push(light.irradiance.as_vec3());
            }
            let mut triangles = tri.triangles.clone();
            stats.constrained_edges += tri.constrained_edges.len();
            let copies = contact::split_contact_vertices(tri, &self.contacts[p], self.coincident);
            let values = contact::side_values(&self.points, p, tri, &copies, nudge);
            stats.evaluations += copies.len();
            for ((slots, v, _), value) in copies.into_iter().zip(values) {
                let Some(slots) = slots else {
                    mesh.radiosity[(base + v) as usize] = value.radiosity.as_vec3();
                    mesh.irradiance[(base + v) as usize] = value.irradiance.as_vec3();
                    continue;
                };
                stats.split_vertices += 1;
                let copy = mesh.positions.len() as u32 - base;
                mesh.positions.push(tri.positions[v as usize].as_vec3());
                mesh.normals.push(normal);
                mesh.patch.push(p as u32);
                mesh.radiosity.push(value.radiosity.as_vec3());
                mesh.irradiance.push(value.irradiance.as_vec3());
                for (t, corner) in slots {
                    triangles[t][corner] = copy;
                }
            }
            mesh.triangles
                .extend(triangles.iter().map(|t| t.map(|i| base + i)));
        }
        stats.evaluate_seconds += t.elapsed().as_secs_f64();
        mesh
    }
}

/// A vertex value's cache key: its patch and exact position.
type Key = (u32, PositionKey);

fn key(patch: usize, x: DVec3) -> Key {
    (patch as u32, position_key(x))
}

/// The radiosity and irradiance at every vertex (and adaptivity's
/// centroid) evaluated so far, by patch and exact position: a point kept
/// from one triangulation to the next is evaluated once. Each batch of
/// evaluations shows as an "output mesh" bar of the run's progress.
#[derive(Default)]
struct ValueCache(HashMap<Key, PointLight>, Progress);

impl ValueCache {
    /// The radiosity at vertex `x` of patch `patch` (evaluated before).
    fn get(&self, patch: usize, x: DVec3) -> DVec3 {
        self.light(patch, x).radiosity
    }

    /// The radiosity and irradiance at vertex `x` of patch `patch`
    /// (evaluated before).
    fn light(&self, patch: usize, x: DVec3) -> PointLight {
        self.0[&key(patch, x)]
    }

    /// Evaluates every vertex of `tris` not in the cache yet; returns how
    /// many.
    fn evaluate_new(&mut self, tris: &[PatchTriangulation], points: &PointEvaluator) -> usize {
        let all: Vec<(usize, DVec3)> = tris
            .iter()
            .enumerate()
            .flat_map(|(p, tri)| tri.positions.iter().map(move |&x| (p, x)))
            .collect();
        self.evaluate(&all, points)
    }

    /// Evaluates every point (patch, position) of `at` not in the cache yet
    /// (in parallel, each into its own slot); returns how many.
    fn evaluate(&mut self, at: &[(usize, DVec3)], points: &PointEvaluator) -> usize {
        let mut seen = HashSet::new();
        let missing: Vec<(usize, DVec3)> = at
            .iter()
            .copied()
            .filter(|&(p, x)| !self.0.contains_key(&key(p, x)) && seen.insert(key(p, x)))
            .collect();
        let phase = self.1.phase("output mesh", missing.len() as u64);
        phase.message(format!("{} vertices", self.0.len() + missing.len()));
        let values: Vec<PointLight> = missing
            .par_iter()
            .with_min_len(16)
            .map(|&(p, x)| points.value(p, x, LinkRays::Bright))
            .inspect(|_| phase.inc(1))
            .collect();
        for (&(p, x), v) in missing.iter().zip(values) {
            self.0.insert(key(p, x), v);
        }
        missing.len()
    }
}
