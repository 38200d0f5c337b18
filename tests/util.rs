//! Helpers shared by the integration tests: tiny glTF scenes written on the
//! fly, and running the `nusselt` binary.

use std::path::Path;
use std::process::{Command, Output};

use base64::Engine;

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

/// Runs the binary with `args`.
pub fn nusselt(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_nusselt"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("the nusselt binary runs")
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
