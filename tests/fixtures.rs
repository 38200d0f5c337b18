//! Fixtures shared by the topic modules (each used by more than one):
//! the slow-test gate; the bundled scenes' paths and loaders; scenes built
//! in code (the furnace box, the furnished room); tiny glTF files written on
//! the fly; the bundled files read back with the `gltf` crate alone (and
//! the scene generator they come from); running the binary; thread pools.

use std::collections::HashMap;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use base64::Engine;
use glam::{DVec3, Mat4};
use nusselt::load::{LoadOptions, load_scene};
use nusselt::scene::{InputTriangle, Material, Scene, Surface};

/// The scene generator of `tools/scenegen/`, compiled into the tests.
#[path = "../tools/scenegen/mod.rs"]
pub mod scenegen;

// The slow-test gate.

/// Whether slow tests are on (`NUSSELT_SLOW_TESTS=1`). When they are not,
/// says on stderr that `name` is skipped.
pub fn slow_tests(name: &str) -> bool {
    let on = std::env::var_os("NUSSELT_SLOW_TESTS").is_some_and(|v| v == "1");
    if !on {
        eprintln!("skipped: {name} (set NUSSELT_SLOW_TESTS=1 to run it)");
    }
    on
}

// The bundled scenes.

/// `scenes/` in the repository.
fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

/// `scenes/<name>`, e.g. `cornell-box.gltf` or `stress/slivers.gltf`.
pub fn scene_path(name: &str) -> PathBuf {
    scenes_dir().join(name)
}

/// [`scene_path`] as a command-line argument.
pub fn scene_arg(name: &str) -> String {
    scene_path(name).to_string_lossy().into_owned()
}

/// `scenes/<name>` through the project's loader, default options.
pub fn bundled_scene(name: &str) -> Scene {
    let path = scene_path(name);
    load_scene(&path, &LoadOptions::default()).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The bundled Cornell box.
pub fn cornell() -> Scene {
    bundled_scene("cornell-box.gltf")
}

/// The stress scene `scenes/stress/<name>.gltf`.
pub fn stress_scene(name: &str) -> Scene {
    bundled_scene(&format!("stress/{name}.gltf"))
}

// Scenes built in code.

/// A closed box (sides `size`) seen from inside, every face emitting
/// radiance `le` with reflectance `rho`.
pub fn furnace_box(size: DVec3, le: f64, rho: f64) -> Scene {
    furnace_box_rgb(size, DVec3::splat(le), rho)
}

/// [`furnace_box`] with a per-channel emitted radiance.
pub fn furnace_box_rgb(size: DVec3, le: DVec3, rho: f64) -> Scene {
    let s = size;
    let p = |x: f64, y: f64, z: f64| DVec3::new(x * s.x, y * s.y, z * s.z);
    let quads = [
        [p(0., 0., 0.), p(0., 0., 1.), p(1., 0., 1.), p(1., 0., 0.)],
        [p(0., 1., 0.), p(1., 1., 0.), p(1., 1., 1.), p(0., 1., 1.)],
        [p(0., 0., 0.), p(1., 0., 0.), p(1., 1., 0.), p(0., 1., 0.)],
        [p(0., 0., 1.), p(0., 1., 1.), p(1., 1., 1.), p(1., 0., 1.)],
        [p(0., 0., 0.), p(0., 1., 0.), p(0., 1., 1.), p(0., 0., 1.)],
        [p(1., 0., 0.), p(1., 0., 1.), p(1., 1., 1.), p(1., 1., 0.)],
    ];
    let mut tris = Vec::new();
    for (k, q) in quads.iter().enumerate() {
        for t in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
            tris.push(InputTriangle {
                positions: t,
                material: 0,
                surface: k as u32,
                reflectance: DVec3::splat(rho),
                emitted_radiance: le,
                origin: Default::default(),
            });
        }
    }
    let material = Material {
        name: "furnace".into(),
        reflectance: DVec3::splat(rho),
        emitted_radiance: le,
        double_sided: false,
    };
    let surfaces = (0..6)
        .map(|k| Surface {
            name: format!("face{k}"),
            node: k,
        })
        .collect();
    Scene::build(tris, vec![material], surfaces, vec![], vec![]).unwrap()
}

/// The quad `q` (counter-clockwise seen from the front) as an n × n grid
/// of quads, two triangles each.
fn grid(q: [DVec3; 4], n: usize, surface: u32, material: u32, out: &mut Vec<InputTriangle>) {
    let at = |i: usize, j: usize| {
        let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
        (1.0 - u) * (1.0 - v) * q[0] + u * (1.0 - v) * q[1] + u * v * q[2] + (1.0 - u) * v * q[3]
    };
    for i in 0..n {
        for j in 0..n {
            let c = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
            for positions in [[c[0], c[1], c[2]], [c[0], c[2], c[3]]] {
                out.push(InputTriangle {
                    positions,
                    material,
                    surface,
                    reflectance: DVec3::ZERO,
                    emitted_radiance: DVec3::ZERO,
                    origin: Default::default(),
                });
            }
        }
    }
}

/// The six faces of the box [lo, hi], counter-clockwise seen from outside
/// (reverse each for the inside), bottom face first.
pub fn box_faces(lo: DVec3, hi: DVec3) -> [[DVec3; 4]; 6] {
    let p = |x: f64, y: f64, z: f64| {
        DVec3::new(
            lo.x + x * (hi.x - lo.x),
            lo.y + y * (hi.y - lo.y),
            lo.z + z * (hi.z - lo.z),
        )
    };
    [
        [p(0., 0., 0.), p(1., 0., 0.), p(1., 0., 1.), p(0., 0., 1.)],
        [p(0., 1., 0.), p(0., 1., 1.), p(1., 1., 1.), p(1., 1., 0.)],
        [p(0., 0., 0.), p(0., 1., 0.), p(1., 1., 0.), p(1., 0., 0.)],
        [p(0., 0., 1.), p(1., 0., 1.), p(1., 1., 1.), p(0., 1., 1.)],
        [p(0., 0., 0.), p(0., 0., 1.), p(0., 1., 1.), p(0., 1., 0.)],
        [p(1., 0., 0.), p(1., 1., 0.), p(1., 1., 1.), p(1., 0., 1.)],
    ]
}

/// How [`room`] is lit and furnished.
#[derive(Clone, Copy)]
pub struct Room {
    /// Grid cells per face side.
    pub n: usize,
    /// Boxes standing on the floor (open at the bottom: the floor under
    /// them is buried), or floating 0.3 m above it (closed).
    pub blocks: usize,
    pub floating: bool,
    pub rho: f64,
    /// Every surface emits E = π W/m² (a furnace); else only a 1 m² ceiling
    /// panel does.
    pub furnace: bool,
}

/// A closed 4 × 3 × 5 m room, each face an n × n grid, with boxes (n/2 ×
/// n/2 grids per face) as `spec` says; reflectance ρ everywhere but the
/// panel.
pub fn room(spec: Room) -> Scene {
    let Room {
        n,
        blocks,
        floating,
        rho,
        furnace,
    } = spec;
    let mut quads = Vec::new();
    for q in box_faces(DVec3::ZERO, DVec3::new(4.0, 3.0, 5.0)) {
        quads.push(([q[0], q[3], q[2], q[1]], n, false));
    }
    let y = 2.99;
    let lamp = [
        DVec3::new(1.5, y, 2.0),
        DVec3::new(2.5, y, 2.0),
        DVec3::new(2.5, y, 3.0),
        DVec3::new(1.5, y, 3.0),
    ];
    if !furnace {
        quads.push((lamp, 1, true));
    }
    let lift = if floating { 0.3 } else { 0.0 };
    for b in 0..blocks {
        let x = 0.4 + 1.2 * b as f64;
        let lo = DVec3::new(x, lift, 0.6 + 0.9 * b as f64);
        let hi = lo + DVec3::new(0.8, 0.5 + 0.3 * b as f64, 0.7);
        let faces = box_faces(lo, hi);
        for q in &faces[usize::from(!floating)..] {
            quads.push((*q, (n / 2).max(1), false));
        }
    }
    painted(&quads, rho, if furnace { 1.0 } else { 0.0 })
}

/// A scene of quads, each an n × n grid (counter-clockwise seen from the
/// front, one surface each): a wall (reflectance `rho`, radiance `glow`)
/// or, when marked, a black lamp of radiance 1.
pub fn painted(quads: &[([DVec3; 4], usize, bool)], rho: f64, glow: f64) -> Scene {
    painted_lit(quads, rho, glow, nusselt::scene::Lights::default())
}

/// [`painted`], lit also (or only) by `lights`.
pub fn painted_lit(
    quads: &[([DVec3; 4], usize, bool)],
    rho: f64,
    glow: f64,
    lights: nusselt::scene::Lights,
) -> Scene {
    let mut tris = Vec::new();
    let mut surfaces = Vec::new();
    for (s, &(q, n, lamp)) in quads.iter().enumerate() {
        surfaces.push(Surface {
            name: format!("s{s}"),
            node: s,
        });
        grid(q, n, s as u32, u32::from(lamp), &mut tris);
    }
    let materials = vec![
        Material {
            name: "wall".into(),
            reflectance: DVec3::splat(rho),
            emitted_radiance: DVec3::splat(glow),
            double_sided: false,
        },
        Material {
            name: "lamp".into(),
            reflectance: DVec3::ZERO,
            emitted_radiance: DVec3::ONE,
            double_sided: false,
        },
    ];
    for t in &mut tris {
        let m = &materials[t.material as usize];
        t.reflectance = m.reflectance;
        t.emitted_radiance = m.emitted_radiance;
    }
    Scene::build_lit(tris, materials, surfaces, vec![], vec![], lights).unwrap()
}

/// The test room: a 6 × 6 grid per face, three boxes on the floor, ρ 0.5,
/// lit by the ceiling panel.
pub const LIT_ROOM: Room = Room {
    n: 6,
    blocks: 3,
    floating: false,
    rho: 0.5,
    furnace: false,
};

// glTF files written on the fly.

/// A triangle-list mesh for [`gltf_json`].
pub struct TestMesh {
    pub name: &'static str,
    pub positions: Vec<[f32; 3]>,
    pub indices: Vec<u32>,
    /// Emitted radiance factor (strength 1) and base colour.
    pub emissive: [f32; 3],
    pub base_color: [f32; 3],
}

/// A `.gltf` with one node per mesh and an embedded (data URI) buffer.
pub fn gltf_json(meshes: &[TestMesh]) -> String {
    let mut buffer = Vec::<u8>::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut gl_meshes = Vec::new();
    let mut materials = Vec::new();
    let mut nodes = Vec::new();
    for (k, m) in meshes.iter().enumerate() {
        let pos_offset = buffer.len();
        for p in &m.positions {
            for c in p {
                buffer.extend_from_slice(&c.to_le_bytes());
            }
        }
        let idx_offset = buffer.len();
        for i in &m.indices {
            buffer.extend_from_slice(&i.to_le_bytes());
        }
        let finite: Vec<[f32; 3]> = m
            .positions
            .iter()
            .copied()
            .filter(|p| p.iter().all(|c| c.is_finite()))
            .collect();
        let lo = (0..3)
            .map(|a| finite.iter().map(|p| p[a]).fold(f32::INFINITY, f32::min))
            .collect::<Vec<_>>();
        let hi = (0..3)
            .map(|a| {
                finite
                    .iter()
                    .map(|p| p[a])
                    .fold(f32::NEG_INFINITY, f32::max)
            })
            .collect::<Vec<_>>();
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{pos_offset},"byteLength":{}}}"#,
            idx_offset - pos_offset
        ));
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{idx_offset},"byteLength":{}}}"#,
            m.indices.len() * 4
        ));
        accessors.push(format!(
            r#"{{"bufferView":{},"componentType":5126,"count":{},"type":"VEC3","min":[{},{},{}],"max":[{},{},{}]}}"#,
            2 * k,
            m.positions.len(),
            lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
        ));
        accessors.push(format!(
            r#"{{"bufferView":{},"componentType":5125,"count":{},"type":"SCALAR"}}"#,
            2 * k + 1,
            m.indices.len()
        ));
        gl_meshes.push(format!(
            r#"{{"name":"{}","primitives":[{{"attributes":{{"POSITION":{}}},"indices":{},"material":{k}}}]}}"#,
            m.name,
            2 * k,
            2 * k + 1
        ));
        materials.push(format!(
            r#"{{"name":"{}-material","pbrMetallicRoughness":{{"baseColorFactor":[{},{},{},1],"metallicFactor":0}},"emissiveFactor":[{},{},{}]}}"#,
            m.name, m.base_color[0], m.base_color[1], m.base_color[2], m.emissive[0], m.emissive[1], m.emissive[2]
        ));
        nodes.push(format!(r#"{{"name":"{}","mesh":{k}}}"#, m.name));
    }
    let data = base64::engine::general_purpose::STANDARD.encode(&buffer);
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[{}]}}],"nodes":[{}],"meshes":[{}],"materials":[{}],"accessors":[{}],"bufferViews":[{}],"buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{data}"}}]}}"#,
        (0..meshes.len())
            .map(|i| i.to_string())
            .collect::<Vec<_>>()
            .join(","),
        nodes.join(","),
        gl_meshes.join(","),
        materials.join(","),
        accessors.join(","),
        views.join(","),
        buffer.len()
    )
}

/// An axis-aligned box of side `s` seen from inside (faces point inward),
/// as six quads; the top face (+y) emits `light`.
pub fn inward_box(s: f32, light: [f32; 3], rho: [f32; 3]) -> Vec<TestMesh> {
    // Each face: four corners counter-clockwise seen from inside.
    let faces: [(&'static str, [[f32; 3]; 4]); 6] = [
        (
            "floor",
            [[0., 0., 0.], [0., 0., 1.], [1., 0., 1.], [1., 0., 0.]],
        ),
        (
            "ceiling",
            [[0., 1., 0.], [1., 1., 0.], [1., 1., 1.], [0., 1., 1.]],
        ),
        (
            "back",
            [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]],
        ),
        (
            "front",
            [[0., 0., 1.], [0., 1., 1.], [1., 1., 1.], [1., 0., 1.]],
        ),
        (
            "left",
            [[0., 0., 0.], [0., 1., 0.], [0., 1., 1.], [0., 0., 1.]],
        ),
        (
            "right",
            [[1., 0., 0.], [1., 0., 1.], [1., 1., 1.], [1., 1., 0.]],
        ),
    ];
    faces
        .iter()
        .map(|(name, q)| TestMesh {
            name,
            positions: q.iter().map(|p| p.map(|c| c * s)).collect(),
            indices: vec![0, 1, 2, 0, 2, 3],
            emissive: if *name == "ceiling" { light } else { [0.0; 3] },
            base_color: rho,
        })
        .collect()
}

// The bundled files read back with the `gltf` crate alone.

/// One world-space triangle of a scene, with the node it came from.
#[derive(Clone, Debug)]
pub struct Tri {
    pub node: String,
    pub material: usize,
    pub p: [DVec3; 3],
    /// The exact f32 world positions, for edge matching.
    key: [[u32; 3]; 3],
}

impl Tri {
    pub fn normal(&self) -> DVec3 {
        (self.p[1] - self.p[0])
            .cross(self.p[2] - self.p[0])
            .normalize()
    }
    pub fn area(&self) -> f64 {
        0.5 * (self.p[1] - self.p[0])
            .cross(self.p[2] - self.p[0])
            .length()
    }
    pub fn centroid(&self) -> DVec3 {
        (self.p[0] + self.p[1] + self.p[2]) / 3.0
    }
}

/// A camera node in world space.
#[derive(Clone, Copy, Debug)]
pub struct View {
    pub eye: DVec3,
    pub forward: DVec3,
    pub up: DVec3,
    pub right: DVec3,
    pub yfov: f64,
    pub aspect: f64,
}

impl View {
    /// The ray through image point (u, v), u to the right, v downwards, in [0, 1].
    pub fn ray(&self, u: f64, v: f64) -> DVec3 {
        let h = (self.yfov / 2.0).tan();
        (self.forward
            + (2.0 * u - 1.0) * h * self.aspect * self.right
            + (1.0 - 2.0 * v) * h * self.up)
            .normalize()
    }
}

/// A bundled scene as [`read_gltf`] reads it.
pub struct Loaded {
    pub doc: gltf::Document,
    pub tris: Vec<Tri>,
    pub views: Vec<View>,
}

/// Reads `scenes/<file>` with the `gltf` crate alone: every triangle in
/// world space and every camera.
pub fn read_gltf(file: &str) -> Loaded {
    let path = scene_path(file);
    let (doc, buffers, _) = gltf::import(&path).unwrap_or_else(|e| panic!("{file}: {e}"));
    let mut tris = Vec::new();
    let mut views = Vec::new();
    let scene = doc.default_scene().expect("a default scene");
    let mut stack: Vec<(gltf::Node, Mat4)> = scene.nodes().map(|n| (n, Mat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        let name = node.name().expect("every node is named").to_owned();
        if let Some(mesh) = node.mesh() {
            assert!(
                mesh.name().is_some(),
                "{file}: mesh of node {name} has no name"
            );
            for prim in mesh.primitives() {
                assert_eq!(prim.mode(), gltf::mesh::Mode::Triangles);
                let reader = prim.reader(|b| Some(&buffers[b.index()]));
                let pos: Vec<[f32; 3]> = reader.read_positions().expect("positions").collect();
                let idx: Vec<u32> = reader.read_indices().expect("indices").into_u32().collect();
                assert_eq!(idx.len() % 3, 0);
                for t in idx.chunks_exact(3) {
                    let w =
                        [t[0], t[1], t[2]].map(|i| world.transform_point3(pos[i as usize].into()));
                    tris.push(Tri {
                        node: name.clone(),
                        material: prim.material().index().expect("a material"),
                        p: w.map(|q| q.as_dvec3()),
                        key: w.map(|q| q.to_array().map(f32::to_bits)),
                    });
                }
            }
        }
        if let Some(camera) = node.camera() {
            let gltf::camera::Projection::Perspective(p) = camera.projection() else {
                panic!("{file}: camera {name} is not perspective");
            };
            views.push(View {
                eye: world.transform_point3(glam::Vec3::ZERO).as_dvec3(),
                forward: world
                    .transform_vector3(glam::Vec3::NEG_Z)
                    .as_dvec3()
                    .normalize(),
                up: world
                    .transform_vector3(glam::Vec3::Y)
                    .as_dvec3()
                    .normalize(),
                right: world
                    .transform_vector3(glam::Vec3::X)
                    .as_dvec3()
                    .normalize(),
                yfov: f64::from(p.yfov()),
                aspect: f64::from(p.aspect_ratio().expect("an aspect ratio")),
            });
        }
        stack.extend(node.children().map(|c| (c, world)));
    }
    Loaded { doc, tris, views }
}

/// `n` directions spread evenly over the sphere (Fibonacci lattice).
pub fn sphere_directions(n: usize) -> Vec<DVec3> {
    let golden = PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - y * y).sqrt();
            let a = golden * i as f64;
            DVec3::new(r * a.cos(), y, r * a.sin())
        })
        .collect()
}

/// Every directed edge must meet its reverse exactly once.
pub fn assert_closed_oriented(file: &str, tris: &[&Tri]) {
    let mut edges: HashMap<([u32; 3], [u32; 3]), usize> = HashMap::new();
    for t in tris {
        for k in 0..3 {
            *edges.entry((t.key[k], t.key[(k + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &edges {
        let back = edges.get(&(b, a)).copied().unwrap_or(0);
        assert!(
            n == 1 && back == 1,
            "{file}: edge {:?} → {:?} used {n} times, its reverse {back} times",
            a.map(f32::from_bits),
            b.map(f32::from_bits)
        );
    }
}

/// Emitted radiance of material `m` as the contract defines it.
pub fn radiance(doc: &gltf::Document, m: usize) -> DVec3 {
    let mat = doc.materials().nth(m).unwrap();
    let s = mat.emissive_strength().unwrap_or(1.0);
    DVec3::from(mat.emissive_factor().map(|c| f64::from(c * s)))
}

// The binary and thread pools.

/// Runs the binary with `args`.
pub fn nusselt(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_nusselt"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("the nusselt binary runs")
}

/// Runs the binary with `args` and asserts that it succeeded.
pub fn nusselt_ok(args: &[&str], cwd: &Path) -> Output {
    let out = nusselt(args, cwd);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Asserts B = E + ρ H at every vertex of `mesh` (E and ρ of its patch in
/// `scene`, to 10⁻⁵ of max(B, 1)); `what` names the run in messages.
pub fn assert_light_adds_up(scene: &Scene, mesh: &nusselt::mesh::OutputMesh, what: &str) {
    for k in 0..mesh.vertex_count() {
        let p = &scene.patches[mesh.patch[k] as usize];
        let (b, h) = (mesh.radiosity[k].as_dvec3(), mesh.irradiance[k].as_dvec3());
        let expected = p.emission + p.reflectance * h;
        assert!(
            (b - expected).abs().max_element() <= 1e-5 * b.max_element().max(1.0),
            "{what}: vertex {k}: B {b}, E + ρH {expected}"
        );
    }
}

/// Asserts a failed run: exit code 1 and exactly one stderr line, starting
/// with `error:` and containing `needle`.
pub fn assert_user_error(out: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "stderr: {stderr}");
    let lines: Vec<&str> = stderr
        .lines()
        .filter(|l| !l.starts_with("warning:"))
        .collect();
    assert_eq!(lines.len(), 1, "one error line expected, got: {stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    assert!(lines[0].contains(needle), "'{needle}' not in: {stderr}");
    assert!(
        !stderr.contains("panicked") && !stderr.contains("backtrace"),
        "{stderr}"
    );
}

/// Runs `f` in a fresh rayon pool of `threads` threads (thread-count
/// independence checks).
pub fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

/// A quick whole solve: the preview preset, a 16 × 16 render of one sample,
/// and a lightmap of that side when given.
pub fn preview_settings(lightmap: Option<u32>) -> nusselt::SolveSettings {
    use nusselt::render::RenderSettings;
    use nusselt::render::view::ViewOverrides;
    use nusselt::{Accuracy, HierarchicalSettings, Preset};
    nusselt::SolveSettings {
        hierarchical: HierarchicalSettings {
            accuracy: Accuracy::preset(Preset::Preview),
            ..HierarchicalSettings::default()
        },
        render: RenderSettings::with_samples(1, 0),
        view: ViewOverrides {
            width: Some(16),
            height: Some(16),
            ..ViewOverrides::default()
        },
        lightmap,
        ..nusselt::SolveSettings::default()
    }
}
