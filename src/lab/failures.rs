//! The failure-mode table: every method on every stress scene, measured.
//!
//! Owns: the methods of the table ([`table_methods`]: each form-factor
//! kernel under Gauss-Seidel, each classic solver with the point-polygon
//! kernel, and the hierarchical solver with each output-mesh mode), the
//! closed forms a stress scene has ([`closed_form`]), running one method
//! within its budget and measuring it ([`measure`]), naming the symptoms
//! ([`symptoms`]) and writing the Markdown table ([`markdown`]).
//! `cargo run --release --example failure-table` drives it.
//!
//! Invariants:
//! - A run that fails, panics or produces non-finite values is a row of the
//!   table, never an abort: the table documents failures, so it must
//!   survive them.
//! - Every run has a budget (sweeps, shots, links, the dense matrix's
//!   memory) and reports whether it converged within it.
//! - The yardsticks are independent of the methods measured: the closed
//!   forms of [`crate::formfactor::closed_form`] and Lambert's point-to-polygon formula
//!   for power, and the path tracer of [`crate::reference`] for the image.
//! - Symptoms are derived from the measurements by fixed rules
//!   ([`symptoms`]), so regenerating the table cannot flatter a method.

use std::f64::consts::PI;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;
use std::time::Instant;

use glam::DVec3;

use crate::classic::matrix::{Kernel, MatrixSettings};
use crate::classic::solve::{ClassicMethod, Convergence};
use crate::error::Result;
use crate::formfactor::form_factor_point_polygon;
use crate::hierarchical::{Accuracy, Budget, HierarchicalSettings};
use crate::meshing::{MeshMode, MeshSettings};
use crate::output;
use crate::pipeline::{self, Method, SolveSettings};
use crate::reference::{self, ReferenceSettings};
use crate::render::RenderSettings;
use crate::render::frame::Frame;
use crate::render::view::{View, ViewOverrides};
use crate::scene::{Patch, Scene, Shape};
use crate::util::progress::Progress;
use crate::visibility::TriangleBvh;

/// The table's view, samples and budgets.
#[derive(Clone, Debug, PartialEq)]
pub struct TableSettings {
    pub width: u32,
    pub height: u32,
    /// Paths per pixel of the reference.
    pub reference_spp: u32,
    /// Samples per pixel of each method's render.
    pub render_spp: u32,
    pub seed: u64,
    /// Gathering budget: sweeps (Jacobi, Gauss-Seidel; per round for the
    /// hierarchical solver).
    pub max_sweeps: usize,
    /// Shooting budget: shots.
    pub max_shots: usize,
    /// Hierarchical link budget.
    pub max_links: u64,
}

impl Default for TableSettings {
    fn default() -> Self {
        TableSettings {
            width: 96,
            height: 64,
            reference_spp: 1024,
            render_spp: 16,
            seed: 0,
            max_sweeps: 1000,
            max_shots: 200_000,
            max_links: 1_000_000,
        }
    }
}

impl TableSettings {
    /// The scene camera's view at the table's size.
    pub fn view(&self) -> ViewOverrides {
        ViewOverrides {
            width: Some(self.width),
            height: Some(self.height),
            ..ViewOverrides::default()
        }
    }
}

/// One method of the table.
#[derive(Clone, Debug)]
pub struct TableMethod {
    pub label: &'static str,
    pub settings: SolveSettings,
}

/// The methods of the table, in table order.
pub fn table_methods(t: &TableSettings) -> Vec<TableMethod> {
    let base = SolveSettings {
        matrix: MatrixSettings {
            seed: t.seed,
            ..MatrixSettings::default()
        },
        render: RenderSettings {
            samples_per_pixel: t.render_spp,
            seed: t.seed,
        },
        view: t.view(),
        convergence: Convergence {
            max_iterations: t.max_sweeps,
            ..Convergence::default()
        },
        ..SolveSettings::default()
    };
    let classic = |method: ClassicMethod, kernel: Kernel| {
        let mut s = SolveSettings {
            method: Method::Classic(method),
            ..base.clone()
        };
        s.matrix.kernel = kernel;
        if method == ClassicMethod::Shooting {
            s.convergence.max_iterations = t.max_shots;
        }
        s
    };
    let hierarchical = |mode: MeshMode| SolveSettings {
        method: Method::Hierarchical,
        hierarchical: HierarchicalSettings {
            accuracy: Accuracy {
                max_links: Some(t.max_links),
                ..Accuracy::default()
            },
            seed: t.seed,
            ..HierarchicalSettings::default()
        },
        mesh: MeshSettings {
            mode,
            ..MeshSettings::default()
        },
        ..base.clone()
    };
    use ClassicMethod::*;
    vec![
        TableMethod {
            label: "Gauss-Seidel, point-polygon",
            settings: classic(GaussSeidel, Kernel::PointPolygon),
        },
        TableMethod {
            label: "Gauss-Seidel, polygon-polygon",
            settings: classic(GaussSeidel, Kernel::PolygonPolygon),
        },
        TableMethod {
            label: "Gauss-Seidel, sampling",
            settings: classic(GaussSeidel, Kernel::Sampling),
        },
        TableMethod {
            label: "Gauss-Seidel, hemicube",
            settings: classic(GaussSeidel, Kernel::Hemicube),
        },
        TableMethod {
            label: "direct, point-polygon",
            settings: classic(Direct, Kernel::PointPolygon),
        },
        TableMethod {
            label: "Jacobi, point-polygon",
            settings: classic(Jacobi, Kernel::PointPolygon),
        },
        TableMethod {
            label: "shooting, point-polygon",
            settings: classic(Shooting, Kernel::PointPolygon),
        },
        TableMethod {
            label: "hierarchical, uniform mesh",
            settings: hierarchical(MeshMode::Uniform),
        },
        TableMethod {
            label: "hierarchical, quadtree mesh",
            settings: hierarchical(MeshMode::Quadtree),
        },
        TableMethod {
            label: "hierarchical, discontinuity mesh",
            settings: hierarchical(MeshMode::Discontinuity),
        },
    ]
}

/// Which power a closed form gives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    /// Σ (1 − ρ) H A over every patch.
    Absorbed,
    /// Σ B A over every patch.
    Radiated,
}

/// A stress scene's exact power, channel mean, in watts.
#[derive(Clone, Debug, PartialEq)]
pub struct ClosedForm {
    pub quantity: Quantity,
    pub watts: f64,
    /// Where the value comes from, for the table.
    pub why: &'static str,
}

fn mean3(v: DVec3) -> f64 {
    (v.x + v.y + v.z) / 3.0
}

/// The closed form of the stress scene `name` (file stem), if it has one.
/// `None` also when the scene does not have the shape its name promises.
pub fn closed_form(name: &str, scene: &Scene) -> Option<ClosedForm> {
    let emitted: DVec3 = scene.patches.iter().map(|p| p.emission * p.area).sum();
    let emitters: Vec<_> = scene
        .patches
        .iter()
        .filter(|p| p.emission.max_element() > 0.0)
        .collect();
    let receivers: Vec<_> = scene
        .patches
        .iter()
        .filter(|p| p.emission.max_element() <= 0.0)
        .collect();
    match name {
        "tiny-emitter" => Some(ClosedForm {
            quantity: Quantity::Absorbed,
            watts: mean3(emitted),
            why: "closed room: absorbed = emitted",
        }),
        "facing-away" => Some(ClosedForm {
            quantity: Quantity::Absorbed,
            watts: 0.0,
            why: "no light reaches any surface: absorbed = 0",
        }),
        "furnace-099" => {
            let rho = scene.patches.first()?.reflectance;
            // Area-weighted means of one f32 reflectance may differ in the
            // last bits.
            let same = |p: &Patch| (p.reflectance - rho).abs().max_element() < 1e-6;
            if !scene.patches.iter().all(same) || rho.max_element() >= 1.0 {
                return None;
            }
            Some(ClosedForm {
                quantity: Quantity::Radiated,
                watts: mean3(emitted / (DVec3::ONE - rho)),
                why: "closed, one reflectance: radiated = Φ / (1 − ρ)",
            })
        }
        "shared-edge" | "open-floor" => {
            let (&[e], &[r]) = (emitters.as_slice(), receivers.as_slice()) else {
                return None;
            };
            if e.reflectance != DVec3::ZERO || r.shape != Shape::Quad {
                return None;
            }
            // The receiver absorbs (1 − ρ) of the light arriving, H(x) =
            // E F(x), and sends ρ H(x) back, of which F(x) reaches the black
            // emitter: absorbed = E ∫ ((1 − ρ) F + ρ F²) dA. Lambert's exact
            // point-to-polygon F, midpoint rule over the receiver.
            let (f, f2) = receiver_integrals(r, e.vertices(), 512);
            let absorbed = e.emission * ((DVec3::ONE - r.reflectance) * f + r.reflectance * f2);
            Some(ClosedForm {
                quantity: Quantity::Absorbed,
                watts: mean3(absorbed),
                why: "one emitter, black, and one flat receiver: E ∫ ((1 − ρ) F + ρ F²) dA \
                      with Lambert's point-to-polygon F",
            })
        }
        _ => None,
    }
}

/// ∫ F dA and ∫ F² dA over the parallelogram patch `receiver`, F the exact
/// point-to-polygon form factor to `source`: the midpoint rule on n × n
/// cells.
pub fn receiver_integrals(receiver: &Patch, source: &[DVec3], n: usize) -> (f64, f64) {
    let (mut f, mut f2) = (0.0, 0.0);
    for i in 0..n {
        for j in 0..n {
            let (u, v) = ((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
            let x = receiver.point(u, v);
            let ff = form_factor_point_polygon(x, receiver.normal, source);
            f += ff;
            f2 += ff * ff;
        }
    }
    let cell = receiver.area / (n * n) as f64;
    (f * cell, f2 * cell)
}

/// The measurements of one run.
#[derive(Clone, Debug, PartialEq)]
pub struct Measure {
    pub converged: bool,
    pub iterations: usize,
    /// Wall-clock seconds of everything but loading, rendering and writing.
    pub seconds: f64,
    pub elements: usize,
    pub links: u64,
    pub vertices: usize,
    /// Absorbed / emitted power (channel means).
    pub absorbed_ratio: f64,
    /// (measured − exact) / exact of the closed form's quantity; / emitted
    /// when the exact value is 0.
    pub power_error: Option<f64>,
    /// RMSE of the render against the reference over the reference's mean.
    pub image_error: f64,
    /// (mean of the render − mean of the reference) / mean of the reference.
    pub image_bias: f64,
    /// Some vertex or pixel is NaN, infinite or negative.
    pub non_finite: bool,
    /// The budget that stopped refinement, if one did.
    pub budget: Option<Budget>,
}

/// What became of one method on one scene.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    Ran(Measure),
    /// The method refused the scene (its error message).
    Refused(String),
    /// The method panicked (the panic message): a bug.
    Panicked(String),
}

/// Reference image, its per-pixel noise, the pixels compared and the
/// seconds it took.
#[derive(Clone, Debug)]
pub struct Reference {
    pub image: Frame,
    pub noise: Frame,
    /// Pixels compared: those not within a pixel of an emitter
    /// ([`receiver_pixels`]).
    pub counted: Vec<bool>,
    /// What image errors are relative to: the reference's mean over the
    /// counted pixels, or where that is 0 (nothing lit), the emitters' mean
    /// radiance.
    pub scale: f64,
    pub seconds: f64,
}

/// Pixels of `view` that see no emitter, even at their edges: 3 × 3 rays
/// per pixel, and the pixels next to one that hits an emitter are dropped
/// too. An emitter's edge is a step from L_e to its surroundings that every
/// method renders alike and the reference anti-aliases with far more
/// samples, so it would dominate the error without saying anything about
/// the solution.
pub fn receiver_pixels(scene: &Scene, view: &View) -> Vec<bool> {
    let bvh = TriangleBvh::of_scene(scene);
    let (w, h) = (view.width as usize, view.height as usize);
    let sees_emitter: Vec<bool> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            (0..9).any(|k| {
                let (sx, sy) = ((k % 3) as f64 / 2.0, (k / 3) as f64 / 2.0);
                let (o, d) = view.ray(x + sx, y + sy);
                bvh.closest_hit(o, d, f64::INFINITY).is_some_and(|hit| {
                    let t = &scene.triangles[hit.triangle as usize];
                    std::iter::once(t.front_patch)
                        .chain(t.back_patch)
                        .any(|p| scene.patches[p as usize].is_emitter())
                })
            })
        })
        .collect();
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            !(-1..=1).any(|dy| {
                (-1..=1).any(|dx| {
                    let (nx, ny) = (x + dx, y + dy);
                    nx >= 0
                        && ny >= 0
                        && (nx as usize) < w
                        && (ny as usize) < h
                        && sees_emitter[ny as usize * w + nx as usize]
                })
            })
        })
        .collect()
}

/// The path-traced reference of `scene` from `view`, read from `cache`
/// (a folder) when a previous run left it there for the same name, size,
/// spp and seed, otherwise rendered and stored there.
pub fn reference(
    scene: &Scene,
    name: &str,
    view: &View,
    t: &TableSettings,
    cache: Option<&Path>,
) -> Result<Reference> {
    let stem = format!(
        "{name}-{}x{}-{}spp-seed{}",
        view.width, view.height, t.reference_spp, t.seed
    );
    let cached = cache.and_then(|dir| {
        let image = output::exr::read_image(&dir.join(format!("{stem}.exr"))).ok()?;
        let noise = output::exr::read_image(&dir.join(format!("{stem}.noise.exr"))).ok()?;
        Some((image, noise, f64::NAN))
    });
    let (image, noise, seconds) = match cached {
        Some(c) => c,
        None => {
            let start = Instant::now();
            let settings = ReferenceSettings {
                samples_per_pixel: t.reference_spp.max(2),
                seed: t.seed,
                max_bounces: None,
            };
            let r = reference::render_reference(scene, view, &settings, &Progress::hidden())?;
            if let Some(dir) = cache {
                output::write_atomic(
                    &dir.join(format!("{stem}.exr")),
                    &output::exr::encode_image(&r.image)?,
                )?;
                output::write_atomic(
                    &dir.join(format!("{stem}.noise.exr")),
                    &output::exr::encode_image(&r.noise)?,
                )?;
            }
            (r.image, r.noise, start.elapsed().as_secs_f64())
        }
    };
    let counted = without_hot_spots(&image, receiver_pixels(scene, view));
    let mut scale = masked_mean(&image, &counted);
    if !(scale > 0.0) {
        let (power, area) = scene
            .patches
            .iter()
            .filter(|p| p.is_emitter())
            .fold((0.0, 0.0), |(w, a), p| {
                (w + mean3(p.emission) * p.area, a + p.area)
            });
        scale = if area > 0.0 { power / area / PI } else { 1.0 };
    }
    Ok(Reference {
        image,
        noise,
        counted,
        scale,
        seconds,
    })
}

/// Pixels whose reference value exceeds this multiple of the median lit
/// pixel are hot spots, left out of the image errors.
pub const HOT_SPOT: f64 = 20.0;

/// `counted` without the hot spots of `image`: pixels brighter than
/// [`HOT_SPOT`] × the median of the counted pixels that are not black. A
/// hot spot (a wall 2 mm from a lamp) is an emitter in all but name: a few
/// sub-pixel features whose value the reference itself resolves only to
/// within its noise, and which would otherwise decide the whole error.
fn without_hot_spots(image: &Frame, mut counted: Vec<bool>) -> Vec<bool> {
    let value = |p: &[f32; 3]| (p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0;
    let mut lit: Vec<f64> = image
        .pixels
        .iter()
        .zip(&counted)
        .filter(|(_, c)| **c)
        .map(|(p, _)| value(p))
        .filter(|&v| v > 0.0)
        .collect();
    if lit.is_empty() {
        return counted;
    }
    let mid = lit.len() / 2;
    let median = *lit.select_nth_unstable_by(mid, f64::total_cmp).1;
    for (c, p) in counted.iter_mut().zip(&image.pixels) {
        if value(p) > HOT_SPOT * median {
            *c = false;
        }
    }
    counted
}

/// The reference's own noise: RMS of its per-pixel standard error over the
/// counted pixels, relative to [`Reference::scale`].
pub fn reference_noise(r: &Reference) -> f64 {
    let squares = Frame {
        pixels: r.noise.pixels.iter().map(|p| p.map(|c| c * c)).collect(),
        ..r.noise.clone()
    };
    masked_mean(&squares, &r.counted).sqrt() / r.scale
}

/// Mean over channels and counted pixels.
fn masked_mean(f: &Frame, counted: &[bool]) -> f64 {
    let (sum, n) = f
        .pixels
        .iter()
        .zip(counted)
        .filter(|(_, c)| **c)
        .fold((0.0, 0usize), |(s, n), (p, _)| {
            (s + p.iter().map(|&c| c as f64).sum::<f64>(), n + 3)
        });
    if n > 0 { sum / n as f64 } else { 0.0 }
}

fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic".into())
}

/// Runs `method` on `scene` and measures it against `exact` and
/// `reference`.
pub fn measure(
    scene: &Scene,
    method: &TableMethod,
    exact: Option<&ClosedForm>,
    reference: &Reference,
) -> Outcome {
    let run = catch_unwind(AssertUnwindSafe(|| {
        pipeline::solve(scene, &method.settings, &Progress::hidden())
    }));
    let run = match run {
        Err(payload) => return Outcome::Panicked(panic_message(payload.as_ref())),
        Ok(Err(e)) => return Outcome::Refused(e.to_string()),
        Ok(Ok(run)) => run,
    };
    let r = &run.report;
    let t = &r.times;
    let power = &r.power;
    let emitted = power.emitted.iter().sum::<f64>() / 3.0;
    let absorbed = power.absorbed.iter().sum::<f64>() / 3.0;
    let power_error = exact.map(|c| {
        let measured = match c.quantity {
            Quantity::Absorbed => absorbed,
            Quantity::Radiated => power.radiated.iter().sum::<f64>() / 3.0,
        };
        if c.watts > 0.0 {
            (measured - c.watts) / c.watts
        } else {
            measured / emitted
        }
    });
    let bad = |v: f32| !(v.is_finite() && v >= 0.0);
    let non_finite = run.frame.pixels.iter().flatten().any(|&v| bad(v))
        || run
            .mesh
            .radiosity
            .iter()
            .any(|b| b.to_array().into_iter().any(bad));
    let (image_error, image_bias) = image_errors(&run.frame, reference);
    Outcome::Ran(Measure {
        converged: r.convergence.converged,
        iterations: r.convergence.iterations,
        seconds: t.bvh
            + t.linking
            + t.refinement
            + t.discontinuities
            + t.mesh
            + t.form_factors
            + t.solve
            + t.output_mesh,
        elements: r.counts.elements,
        links: r.counts.links,
        vertices: r.counts.output_vertices,
        absorbed_ratio: if emitted > 0.0 {
            absorbed / emitted
        } else {
            0.0
        },
        power_error,
        image_error,
        image_bias,
        non_finite,
        budget: r.budget.as_ref().map(|b| b.kind),
    })
}

/// RMSE and mean difference of `frame` against the reference over the
/// counted pixels, both relative to [`Reference::scale`].
fn image_errors(frame: &Frame, reference: &Reference) -> (f64, f64) {
    let diff = Frame {
        pixels: frame
            .pixels
            .iter()
            .zip(&reference.image.pixels)
            .map(|(t, r)| [t[0] - r[0], t[1] - r[1], t[2] - r[2]])
            .collect(),
        ..frame.clone()
    };
    let squares = Frame {
        pixels: diff.pixels.iter().map(|p| p.map(|c| c * c)).collect(),
        ..diff.clone()
    };
    let rmse = masked_mean(&squares, &reference.counted).sqrt();
    let bias = masked_mean(&diff, &reference.counted);
    (rmse / reference.scale, bias / reference.scale)
}

/// Tolerances of [`symptoms`].
pub mod limits {
    /// Power above the closed form (or absorbed above emitted) by more than
    /// this fraction is energy created.
    pub const ENERGY_CREATED: f64 = 0.02;
    /// Power below the closed form by more than this fraction is light lost.
    pub const LIGHT_LOST: f64 = 0.05;
    /// A render whose mean is off the reference's by more than this is too
    /// bright or too dark.
    pub const IMAGE_BIAS: f64 = 0.10;
    /// A render whose relative RMSE exceeds this (and twice the reference's
    /// noise) without a bias is blotchy: aliasing or noise.
    pub const IMAGE_ERROR: f64 = 0.25;
    /// A run this many times slower than the scene's fastest, and above
    /// [`SLOW_SECONDS`], is slow.
    pub const SLOW_FACTOR: f64 = 20.0;
    pub const SLOW_SECONDS: f64 = 5.0;
}

/// The symptoms of an outcome, by the rules of [`limits`]; `fastest` is
/// the scene's fastest run in seconds, `noise` the reference's relative
/// noise. Empty when nothing is wrong.
pub fn symptoms(outcome: &Outcome, fastest: f64, noise: f64) -> Vec<String> {
    use limits::*;
    let m = match outcome {
        Outcome::Refused(e) => return vec![format!("refused: {e}")],
        Outcome::Panicked(e) => return vec![format!("PANIC: {e}")],
        Outcome::Ran(m) => m,
    };
    let mut out = Vec::new();
    if m.non_finite {
        out.push("non-finite or negative output (blow-up)".to_string());
    }
    if !m.converged {
        out.push(format!(
            "not converged in {} iterations (slow convergence)",
            m.iterations
        ));
    }
    if let Some(b) = m.budget {
        out.push(format!("refinement stopped at the {} budget", b.noun()));
    }
    match m.power_error {
        Some(e) if e > ENERGY_CREATED => out.push(format!("energy created (+{:.1} %)", 100.0 * e)),
        Some(e) if e < -LIGHT_LOST => out.push(format!("light lost ({:.1} %)", 100.0 * e)),
        None if m.absorbed_ratio > 1.0 + ENERGY_CREATED => out.push(format!(
            "energy created (absorbed {:.3} × emitted)",
            m.absorbed_ratio
        )),
        _ => {}
    }
    if m.image_bias > IMAGE_BIAS {
        out.push(format!("too bright (+{:.0} %)", 100.0 * m.image_bias));
    } else if m.image_bias < -IMAGE_BIAS {
        out.push(format!("too dark ({:.0} %)", 100.0 * m.image_bias));
    } else if m.image_error > IMAGE_ERROR.max(2.0 * noise) {
        out.push(format!(
            "blotchy (image error {:.0} % without bias: aliasing or noise)",
            100.0 * m.image_error
        ));
    }
    if m.seconds > SLOW_SECONDS && m.seconds > SLOW_FACTOR * fastest {
        out.push(format!("slow ({:.0}× the fastest)", m.seconds / fastest));
    }
    out
}

/// Every method on one scene.
#[derive(Clone, Debug)]
pub struct SceneTable {
    pub name: String,
    pub exact: Option<ClosedForm>,
    pub reference_noise: f64,
    pub reference_seconds: f64,
    pub rows: Vec<(&'static str, Outcome)>,
}

impl SceneTable {
    /// The fastest successful run, in seconds.
    pub fn fastest(&self) -> f64 {
        self.rows
            .iter()
            .filter_map(|(_, o)| match o {
                Outcome::Ran(m) => Some(m.seconds),
                _ => None,
            })
            .fold(f64::INFINITY, f64::min)
    }
}

/// Runs every method of `methods` on `scene` (called `name`), against its
/// closed form and its reference (cached in `cache`). `each` is told of
/// every finished row.
pub fn scene_table(
    scene: &Scene,
    name: &str,
    t: &TableSettings,
    methods: &[TableMethod],
    cache: Option<&Path>,
    mut each: impl FnMut(&str, &Outcome),
) -> Result<SceneTable> {
    let view = View::resolve(scene.cameras.first(), scene.bounds, &t.view())?;
    let reference = reference(scene, name, &view, t, cache)?;
    let exact = closed_form(name, scene);
    let mut rows = Vec::new();
    for m in methods {
        let outcome = measure(scene, m, exact.as_ref(), &reference);
        each(m.label, &outcome);
        rows.push((m.label, outcome));
    }
    Ok(SceneTable {
        name: name.to_string(),
        exact,
        reference_noise: reference_noise(&reference),
        reference_seconds: reference.seconds,
        rows,
    })
}

fn percent(x: f64) -> String {
    if x.is_finite() {
        format!("{:+.1} %", 100.0 * x)
    } else {
        "—".into()
    }
}

/// The Markdown table of every scene; `command` is how it was made.
pub fn markdown(tables: &[SceneTable], t: &TableSettings, command: &str) -> String {
    let mut s = String::new();
    s.push_str("# Failure modes: every method on every stress scene\n\n");
    s.push_str(&format!(
        "Generated by `{command}`; do not edit by hand. The scenes are described in \
         [scenes/README.md](../README.md#stress-scenes).\n\n"
    ));
    s.push_str(&format!(
        "Each method runs at its default settings within a budget: {} sweeps \
         (Jacobi, Gauss-Seidel, and per round for the hierarchical solver), {} shots, \
         {} links, and the dense matrix's default memory budget. Classic methods use \
         the default uniform mesh; the hierarchical solver its `default` preset.\n\n",
        t.max_sweeps, t.max_shots, t.max_links
    ));
    s.push_str(&format!(
        "Columns: *time* is the solve without loading, rendering and writing (seconds, \
         2 cores, wall clock); *links¹* are the hierarchical solver's links, or the \
         classic matrix's non-zero form factors; *abs/emit* is the absorbed over the emitted power; \
         *power err* is the error of the scene's closed-form power (relative, or \
         over the emitted power where the exact value is 0); *image err* and *bias* \
         are the relative RMSE and the relative mean difference of a {}×{} render \
         ({} samples per pixel) against the path-traced reference ({} paths per pixel; \
         its own relative noise is given per scene), over the pixels that see no \
         emitter (even at their edges, nor next to one) and no hot spot (brighter than \
         {:.0}× the reference's median lit pixel). *Symptoms* follow fixed rules: \
         energy created above +{:.0} %, light lost below −{:.0} %, too bright or dark \
         beyond ±{:.0} %, blotchy above {:.0} % image error (and twice the reference \
         noise) without bias, slow above {:.0}× the scene's fastest run and {:.0} s.\n\n",
        t.width,
        t.height,
        t.render_spp,
        t.reference_spp,
        HOT_SPOT,
        100.0 * limits::ENERGY_CREATED,
        100.0 * limits::LIGHT_LOST,
        100.0 * limits::IMAGE_BIAS,
        100.0 * limits::IMAGE_ERROR,
        limits::SLOW_FACTOR,
        limits::SLOW_SECONDS,
    ));
    for table in tables {
        s.push_str(&format!("## {}\n\n", table.name));
        match &table.exact {
            Some(c) => s.push_str(&format!(
                "Closed form: {} W {} ({}). ",
                format_watts(c.watts),
                match c.quantity {
                    Quantity::Absorbed => "absorbed",
                    Quantity::Radiated => "radiated",
                },
                c.why
            )),
            None => s.push_str("No closed form: the reference image is the yardstick. "),
        }
        s.push_str(&format!(
            "Reference noise {:.1} %.\n\n",
            100.0 * table.reference_noise
        ));
        s.push_str(
            "| method | converged | time s | elements | links¹ | abs/emit | power err | image err | bias | symptoms |\n",
        );
        s.push_str("|---|---|---:|---:|---:|---:|---:|---:|---:|---|\n");
        let fastest = table.fastest();
        for (label, outcome) in &table.rows {
            let symptoms = symptoms(outcome, fastest, table.reference_noise);
            let symptoms = if symptoms.is_empty() {
                "—".to_string()
            } else {
                symptoms.join("; ").replace('|', "/")
            };
            match outcome {
                Outcome::Ran(m) => s.push_str(&format!(
                    "| {label} | {} | {:.2} | {} | {} | {:.3} | {} | {:.1} % | {} | {symptoms} |\n",
                    if m.converged {
                        format!("yes ({})", m.iterations)
                    } else {
                        format!("**no** ({})", m.iterations)
                    },
                    m.seconds,
                    m.elements,
                    if m.links > 0 {
                        m.links.to_string()
                    } else {
                        "—".into()
                    },
                    m.absorbed_ratio,
                    m.power_error.map_or("—".into(), percent),
                    100.0 * m.image_error,
                    percent(m.image_bias),
                )),
                _ => s.push_str(&format!(
                    "| {label} | — | — | — | — | — | — | — | — | {symptoms} |\n"
                )),
            }
        }
        s.push('\n');
    }
    s
}

fn format_watts(w: f64) -> String {
    if w == 0.0 {
        "0".into()
    } else {
        format!("{w:.6}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formfactor::closed_form::c14;

    fn square(corners: [DVec3; 4]) -> Patch {
        let normal = (corners[1] - corners[0])
            .cross(corners[3] - corners[0])
            .normalize();
        Patch {
            corners,
            shape: Shape::Quad,
            normal,
            area: 1.0,
            material: 0,
            surface: 0,
            side: crate::scene::Side::Front,
            reflectance: DVec3::splat(0.5),
            emission: DVec3::ZERO,
            triangles: [0, 1],
        }
    }

    #[test]
    fn receiver_integral_of_a_shared_edge_matches_howell_c14() {
        // Receiver in z = 0 facing +z, source in y = 0 facing +y; they share
        // the edge x ∈ [0, 1].
        let receiver = square([
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ]);
        assert!((receiver.normal - DVec3::Z).length() < 1e-12);
        let source = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 0.0),
        ];
        let (f, f2) = receiver_integrals(&receiver, &source, 512);
        assert!((f - c14(1.0, 1.0, 1.0)).abs() < 1e-4, "∫F = {f}");
        // F ≤ 1/2 everywhere, so ∫F² lies between (∫F)² and ∫F / 2.
        assert!(f2 > f * f && f2 < 0.5 * f, "∫F² = {f2}");
    }

    fn ran(m: impl FnOnce(&mut Measure)) -> Outcome {
        let mut measure = Measure {
            converged: true,
            iterations: 3,
            seconds: 1.0,
            elements: 10,
            links: 10,
            vertices: 10,
            absorbed_ratio: 0.5,
            power_error: Some(0.0),
            image_error: 0.05,
            image_bias: 0.0,
            non_finite: false,
            budget: None,
        };
        m(&mut measure);
        Outcome::Ran(measure)
    }

    #[test]
    fn symptoms_follow_the_rules() {
        let s = |o: Outcome| symptoms(&o, 1.0, 0.01).join("; ");
        assert_eq!(s(ran(|_| {})), "");
        assert!(s(ran(|m| m.power_error = Some(0.03))).starts_with("energy created"));
        assert!(s(ran(|m| m.power_error = Some(-0.06))).starts_with("light lost"));
        assert_eq!(s(ran(|m| m.power_error = Some(-0.04))), "");
        assert!(
            s(ran(|m| {
                m.power_error = None;
                m.absorbed_ratio = 1.03
            }))
            .starts_with("energy created")
        );
        assert!(s(ran(|m| m.converged = false)).starts_with("not converged in 3"));
        assert!(s(ran(|m| m.image_bias = 0.2)).starts_with("too bright"));
        assert!(s(ran(|m| m.image_bias = -0.2)).starts_with("too dark"));
        assert!(s(ran(|m| m.image_error = 0.3)).starts_with("blotchy"));
        assert!(s(ran(|m| m.seconds = 30.0)).starts_with("slow (30×"));
        assert_eq!(s(ran(|m| m.seconds = 4.0)), "");
        assert!(s(ran(|m| m.non_finite = true)).starts_with("non-finite"));
        assert!(
            s(ran(|m| m.budget = Some(Budget::Elements)))
                .starts_with("refinement stopped at the element budget")
        );
        assert!(s(Outcome::Refused("too big".into())).starts_with("refused: too big"));
        assert!(s(Outcome::Panicked("oops".into())).starts_with("PANIC"));
    }
}
