//! Writes `scenes/README.md` from the scene definitions, so that every
//! number in it (reflectances, radiances, areas, triangle counts, camera,
//! punctual lights) is the one in the files.

use std::f64::consts::PI;
use std::fmt::Write as _;

use anyhow::Result;
use glam::DVec3;

use super::encode::index_mesh;
use super::hard::HardScene;
pub use super::model::triangle_count;
use super::model::{BufferStorage, LightKind, SceneDef, world_transforms};
use super::scale::Plan;
use super::stress::StressScene;

fn rgb(c: [f64; 3]) -> String {
    format!("({}, {}, {})", num(c[0]), num(c[1]), num(c[2]))
}

/// A short decimal: up to 4 significant decimals, trailing zeros dropped.
fn num(x: f64) -> String {
    let s = format!("{x:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".to_owned()
    } else {
        s.to_owned()
    }
}

fn vec3(v: DVec3) -> String {
    format!("({}, {}, {})", num(v.x), num(v.y), num(v.z))
}

fn triangle_area(t: &[DVec3; 3]) -> f64 {
    0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length()
}

/// One scene's section; `dir` prefixes its file names in the heading
/// (empty, or a folder with a trailing `/`); `notes` are extra paragraphs
/// after the description.
fn scene_section(out: &mut String, scene: &SceneDef, dir: &str, notes: &[String]) -> Result<()> {
    let world = world_transforms(scene);
    writeln!(out, "## {} (`{dir}{}.gltf`)\n", scene.title, scene.stem)?;
    writeln!(out, "{}\n", scene.about)?;
    for note in notes {
        writeln!(out, "{note}\n")?;
    }
    match scene.storage {
        BufferStorage::External => writeln!(
            out,
            "Files: `{0}.gltf` with its geometry in `{0}.bin`.\n",
            scene.stem
        )?,
        BufferStorage::Embedded => writeln!(
            out,
            "Files: `{}.gltf` alone; its buffer is embedded as a base64 `data:` URI.\n",
            scene.stem
        )?,
    }

    writeln!(
        out,
        "Materials (all single-sided, metallic 0, roughness 1):\n"
    )?;
    writeln!(
        out,
        "| material | ρ = baseColorFactor.rgb | L_e (W·m⁻²·sr⁻¹) | E = π L_e (W·m⁻²) | notes |"
    )?;
    writeln!(out, "|---|---|---|---|---|")?;
    for m in &scene.materials {
        let (le, e) = match m.emission {
            Some(em) => {
                let l = em.radiance();
                let how = match em.strength {
                    Some(s) => format!(
                        "{} = {} × {} (emissiveFactor × emissiveStrength)",
                        rgb(l),
                        rgb(em.factor),
                        num(s)
                    ),
                    None => format!("{} (emissiveFactor, no strength extension)", rgb(l)),
                };
                (how, rgb(l.map(|c| c * PI)))
            }
            None => ("—".to_owned(), "—".to_owned()),
        };
        writeln!(
            out,
            "| {} | {} | {} | {} | {} |",
            m.name,
            rgb(m.reflectance),
            le,
            e,
            m.note
        )?;
    }

    writeln!(
        out,
        "\nSurfaces (one glTF node each; areas in world space):\n"
    )?;
    writeln!(out, "| node | mesh | material | triangles | area (m²) |")?;
    writeln!(out, "|---|---|---|---|---|")?;
    let (mut n_tris, mut n_verts) = (0, 0);
    let mut power = [0.0f64; 3];
    for (n, node) in scene.nodes.iter().enumerate() {
        let (Some(m), Some(xf)) = (node.mesh, world[n]) else {
            continue;
        };
        let mesh = &scene.meshes[m];
        let area: f64 = mesh
            .triangles
            .iter()
            .map(|t| triangle_area(&t.map(|p| xf.transform_point3(p))))
            .sum();
        n_tris += mesh.triangles.len();
        n_verts += index_mesh(&mesh.name, &mesh.triangles)?.positions.len();
        let material = &scene.materials[mesh.material];
        if let Some(e) = material.emission {
            for (p, l) in power.iter_mut().zip(e.radiance()) {
                *p += PI * l * area;
            }
        }
        writeln!(
            out,
            "| {} | {} | {} | {} | {} |",
            node.name,
            mesh.name,
            material.name,
            mesh.triangles.len(),
            num(area)
        )?;
    }
    if power == [0.0; 3] && !scene.lights.is_empty() {
        writeln!(
            out,
            "\nIn all: {n_tris} triangles, {n_verts} vertices (welded per mesh, counted per \
node). No surface emits: the punctual lights below are the only sources.\n"
        )?;
    } else {
        writeln!(
            out,
            "\nIn all: {n_tris} triangles, {n_verts} vertices (welded per mesh, counted per \
node). Emitted power Σ E·A = {} W per channel.\n",
            rgb(power)
        )?;
    }
    lights_table(out, scene)?;

    for (n, node) in scene.nodes.iter().enumerate() {
        let (Some(c), Some(xf)) = (node.camera, world[n]) else {
            continue;
        };
        let eye = xf.transform_point3(DVec3::ZERO);
        let dir = xf.transform_vector3(DVec3::NEG_Z).normalize();
        let up = xf.transform_vector3(DVec3::Y).normalize();
        writeln!(
            out,
            "Camera `{}`: perspective, at {} m, looking along {}, up {}, vertical field of view \
{}° ({} rad), aspect ratio {}.\n",
            node.name,
            vec3(eye),
            vec3(dir),
            vec3(up),
            num(c.yfov.to_degrees()),
            num(c.yfov),
            num(c.aspect_ratio)
        )?;
    }
    Ok(())
}

/// The scene's `KHR_lights_punctual` lights, one row per node placing one,
/// and how their intensities are read; nothing when it has none.
fn lights_table(out: &mut String, scene: &SceneDef) -> Result<()> {
    if scene.lights.is_empty() {
        return Ok(());
    }
    let world = world_transforms(scene);
    writeln!(
        out,
        "Lights (`KHR_lights_punctual`, listed in `extensionsUsed`; no `range`):\n"
    )?;
    writeln!(
        out,
        "| node | light | type | node position (m) | direction | colour | intensity | \
cone angles inner / outer (rad) |"
    )?;
    writeln!(out, "|---|---|---|---|---|---|---|---|")?;
    for (n, node) in scene.nodes.iter().enumerate() {
        let (Some(k), Some(xf)) = (node.light, world[n]) else {
            continue;
        };
        let light = &scene.lights[k];
        let position = xf.transform_point3(DVec3::ZERO);
        let direction = xf.transform_vector3(DVec3::NEG_Z).normalize();
        let (direction, cone) = match light.kind {
            LightKind::Point => ("— (all round)".to_owned(), "—".to_owned()),
            LightKind::Directional => (vec3(direction), "—".to_owned()),
            LightKind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => (
                vec3(direction),
                format!(
                    "{} / {} ({}° / {}°)",
                    num(inner_cone_angle),
                    num(outer_cone_angle),
                    num(inner_cone_angle.to_degrees()),
                    num(outer_cone_angle.to_degrees())
                ),
            ),
        };
        let unit = match light.kind {
            LightKind::Directional => "W·m⁻²",
            _ => "W·sr⁻¹",
        };
        writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} {unit} | {} |",
            node.name,
            light.name,
            light.kind.name(),
            vec3(position),
            direction,
            rgb(light.color),
            num(light.intensity),
            cone
        )?;
    }
    writeln!(
        out,
        "\nUnits: a point light of intensity I and colour c gives a surface at distance r the \
irradiance c · I cos θ / r² (θ between the surface's normal and the direction to the light), \
in W·m⁻², the units of the emitters' exitance E = π L_e; so I is read as W·sr⁻¹ where the glTF \
spec says candela. A spot light gives the same inside its inner cone and nothing beyond its \
outer cone. A directional light of intensity E gives c · E cos θ everywhere it is not shadowed \
(E read as W·m⁻² where the spec says lux); its node's position only marks where it comes \
from. Spot and directional lights shine down their node's local −z.\n"
    )?;
    Ok(())
}

/// The whole README: the bundled scenes, the stress scenes, then the
/// scale-up family with its bundled member `office`.
pub fn readme(
    scenes: &[SceneDef],
    stress: &[StressScene],
    hard: &[HardScene],
    office: &SceneDef,
) -> Result<String> {
    let mut out = String::new();
    writeln!(out, "# Bundled scenes\n")?;
    writeln!(
        out,
        "These glTF 2.0 files are written by `tools/gen_scenes.rs` (definitions in \
`tools/scenegen/`), and so is this note: do not edit them by hand. Regenerate them, \
byte for byte, with\n\n    cargo run --release --example gen-scenes -- scenes/\n\n\
The test `scenes::bundled_scenes_are_up_to_date` fails when the committed files differ \
from what the generator writes.\n"
    )?;
    writeln!(
        out,
        "Conventions in every scene: lengths in metres, +y up, right-handed; front faces \
counter-clockwise, and every surface's front faces the space it lights or is lit from (room \
walls face into the room, boxes face outwards, lights face down); reflectance \
ρ = `baseColorFactor.rgb`, emitted radiance L_e = `emissiveFactor` × \
`KHR_materials_emissive_strength.emissiveStrength` (1 without the extension), emitted \
exitance E = π L_e; all materials single-sided, `metallicFactor` 0, `roughnessFactor` 1; \
quads are written as two triangles; positions are rounded to the micrometre. Each scene has \
one perspective camera node, which looks down its local −z. Some scenes are lit instead by \
`KHR_lights_punctual` lights (listed in `extensionsUsed`, not required), each placed by a \
node; their sections list them and say how their intensities are read.\n"
    )?;
    writeln!(out, "| scene | title | triangles | buffer |")?;
    writeln!(out, "|---|---|---|---|")?;
    for s in scenes {
        let tris = triangle_count(s);
        let buffer = match s.storage {
            BufferStorage::External => format!("`{}.bin`", s.stem),
            BufferStorage::Embedded => "embedded (base64)".to_owned(),
        };
        writeln!(
            out,
            "| `{}.gltf` | {} | {} | {} |",
            s.stem, s.title, tris, buffer
        )?;
    }
    writeln!(
        out,
        "The stress scenes of `stress/` are listed [further down](#stress-scenes), the hard \
interiors of `hard/` [after them](#hard-interiors), and the scale-up scenes of `scale/` \
[at the end](#scale-up-scenes).\n"
    )?;
    for s in scenes {
        scene_section(&mut out, s, "", &[])?;
    }
    stress_part(&mut out, stress)?;
    hard_part(&mut out, hard)?;
    scale_part(&mut out, office)?;
    Ok(out)
}

/// The scale-up family: what it is for, how to write its members, their
/// plans, then the bundled member's section.
fn scale_part(out: &mut String, office: &SceneDef) -> Result<()> {
    writeln!(out, "# Scale-up scenes\n")?;
    writeln!(
        out,
        "One family of interior scene, an office floor of furnished rooms joined by doors, \
generated at any triangle count by `tools/scenegen/scale.rs`, for the clustering work and \
the benchmarks that measure how time and memory grow with scene size (time per phase, the \
growth exponent of time against triangles). Larger targets get more rooms and a finer \
tessellation of walls and furniture; the triangle count lands within ±15 % of the target \
(checked by `tests/scale_scenes.rs` at 10⁴, 10⁵ and 10⁶). Only the 10⁴-triangle member is \
committed, as `scale/{BUNDLED}.gltf`; write any other size, deterministically, with\n\n    \
cargo run --release --example gen-scenes -- --scale 1000000 DIR\n\n\
which writes `DIR/office-1m.gltf` and `DIR/office-1m.bin`. Furniture is instanced (one mesh \
a piece, placed by nodes), so the files hold the room shells and one copy of each piece: \
writing the 10⁶ member took 0.3 s (0.15 s of CPU, 80 MB peak memory) on the 2-core \
development machine and gave a 7.1 MB `.bin` and a 0.8 MB `.gltf`; the loader expands the \
instances to the full triangle count.\n",
        BUNDLED = office.stem,
    )?;
    writeln!(
        out,
        "| target | file | triangles | in room shells | rooms (x × z) | lit rooms | detail g | \
wall grid (m) |"
    )?;
    writeln!(out, "|---|---|---|---|---|---|---|---|")?;
    for target in super::SCALE_TARGETS {
        let plan = Plan::for_target(target);
        let scene = super::scale::build(&plan);
        // Shells are the root nodes with a mesh; furniture hangs under groups.
        let shells: usize = scene
            .roots
            .iter()
            .filter_map(|&r| scene.nodes[r].mesh)
            .map(|m| scene.meshes[m].triangles.len())
            .sum();
        writeln!(
            out,
            "| {target} | `{}.gltf` | {} | {shells} | {} × {} = {} | {} | {} | {} × {} |",
            scene.stem,
            triangle_count(&scene),
            plan.columns,
            plan.rows,
            plan.rooms(),
            plan.lit_rooms(),
            num(plan.detail),
            num(plan.wall_step()),
            num(0.35 / plan.detail),
        )?;
    }
    writeln!(out)?;
    scene_section(out, office, "scale/", &[])
}

/// The stress scenes: a summary table, then one section each.
fn stress_part(out: &mut String, stress: &[StressScene]) -> Result<()> {
    writeln!(out, "# Stress scenes\n")?;
    writeln!(
        out,
        "The scenes in `stress/` sit where radiosity methods are known to fail: near \
contact, interpenetration, coplanar overlap, slivers, extreme scale ranges, reflectance near \
1, light that reaches nothing, open scenes, thousands of emitters and a singular kernel. Each \
is small, so that the tests in `tests/stress.rs` solve a fast subset of them in seconds and \
check the invariants every method must keep there: no panic, finite and non-negative \
outputs, no energy created, non-convergence reported. The conventions are those above; \
unlike the bundled scenes, some stress scenes overlap or interpenetrate on purpose. \
\"Expected to struggle\" is the literature's and our expectation, not a measurement; \
the measurements are in the failure-mode table, [stress/FAILURES.md](stress/FAILURES.md) \
(`cargo run --release --example failure-table`).\n"
    )?;
    writeln!(out, "| scene | title | triangles | stresses |")?;
    writeln!(out, "|---|---|---|---|")?;
    for s in stress {
        let first = s.stresses.split(':').next().unwrap_or(s.stresses);
        writeln!(
            out,
            "| `stress/{}.gltf` | {} | {} | {} |",
            s.scene.stem,
            s.scene.title,
            triangle_count(&s.scene),
            first
        )?;
    }
    writeln!(out)?;
    for s in stress {
        let notes = [
            format!("**Stresses:** {}", s.stresses),
            format!("**Expected to struggle:** {}", s.struggles),
        ];
        scene_section(out, &s.scene, "stress/", &notes)?;
    }
    Ok(())
}

/// The hard interiors: a summary table, then one section each.
fn hard_part(out: &mut String, hard: &[HardScene]) -> Result<()> {
    writeln!(out, "# Hard interiors\n")?;
    writeln!(
        out,
        "The scenes in `hard/` are closed interiors where most light arrives indirectly, or \
where a thin wall, a narrow gap or a corner must stop it: the scenes the solver's accuracy \
is judged on, against path-traced point references (`nusselt probe`), and the leak and \
energy tests run on (`tests/hard.rs`). One of them is held out: no setting of the solver \
was tuned on it, and its errors are reported apart.\n"
    )?;
    writeln!(out, "| scene | title | triangles | checks |")?;
    writeln!(out, "|---|---|---|---|")?;
    for h in hard {
        writeln!(
            out,
            "| `hard/{}.gltf` | {} | {} | {} |",
            h.scene.stem,
            h.scene.title,
            triangle_count(&h.scene),
            h.checks
        )?;
    }
    writeln!(out)?;
    for h in hard {
        let mut notes = vec![format!("**Checks:** {}.", h.checks)];
        if h.held_out {
            notes.push("**Held out** of every tuning loop.".to_owned());
        }
        scene_section(out, &h.scene, "hard/", &notes)?;
    }
    Ok(())
}
