//! Sizes from input or flags under an address-space limit: the binary runs
//! as a child with `RLIMIT_AS` at [`ADDRESS_SPACE`] (set with `setrlimit`
//! between fork and exec), so an allocation on trust aborts the child
//! ("memory allocation of N bytes failed", exit 134) and fails the test
//! instead of taking the machine's memory.
//!
//! Owns: the limited runner ([`nusselt_limited`]) and the regression cases
//! of issue 26, item 1. Invariants each case checks: a size over
//! `--memory-budget` (default 2 GiB, below the limit) is refused before it
//! is allocated, with exit code 1 and one `error:` line naming the flag or
//! the input element and the memory it would need; no panic, no backtrace,
//! no abort. Inputs are generated here (a few hundred KB each), never
//! committed.

use std::io::Cursor;
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Command, Output};
use std::time::Instant;

use serde_json::json;

use crate::fixtures::{assert_user_error, scene_arg};
use crate::loader::Gltf;

/// The child's address-space limit: above the default 2 GiB budget and
/// what a small solve maps (thread stacks, allocator arenas), below
/// what any of the refused sizes would take.
const ADDRESS_SPACE: u64 = 3 << 30;

/// Runs the binary with `args` in `cwd` under [`ADDRESS_SPACE`]. The
/// allocator is held to two arenas so that the reserved (unused) address
/// space does not grow with the machine's core count.
fn nusselt_limited(args: &[&str], cwd: &Path) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_nusselt"));
    command
        .args(args)
        .current_dir(cwd)
        .env("MALLOC_ARENA_MAX", "2")
        .env_remove("RUST_BACKTRACE");
    let limit = libc::rlimit {
        rlim_cur: ADDRESS_SPACE as libc::rlim_t,
        rlim_max: ADDRESS_SPACE as libc::rlim_t,
    };
    // SAFETY: between fork and exec only the async-signal-safe setrlimit
    // runs, on a value built before the fork.
    unsafe {
        command.pre_exec(move || {
            if libc::setrlimit(libc::RLIMIT_AS, &limit) == 0 {
                Ok(())
            } else {
                Err(std::io::Error::last_os_error())
            }
        });
    }
    let started = Instant::now();
    let out = command.output().expect("the nusselt binary runs");
    eprintln!(
        "{:?} → {:?} in {:.2} s",
        args,
        out.status.code(),
        started.elapsed().as_secs_f64()
    );
    out
}

/// [`assert_user_error`], and no abort: the exit is not a signal or 134.
fn assert_refused(out: &Output, needles: &[&str]) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !stderr.contains("memory allocation of"),
        "aborted on an allocation: {stderr}"
    );
    assert_ne!(out.status.code(), Some(134), "{stderr}");
    for needle in needles {
        assert_user_error(out, needle);
    }
}

#[test]
fn limited_runner_does_not_hinder_a_normal_solve() {
    let dir = tempfile::tempdir().unwrap();
    let cornell = scene_arg("cornell-box.gltf");
    let out = nusselt_limited(
        &[
            "solve",
            &cornell,
            "-o",
            "out",
            "-q",
            "--accuracy",
            "preview",
        ],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn limited_runner_turns_an_abort_into_a_failure() {
    // The limit holds: a budget far above it lets the dense matrix be
    // allocated, and the allocation fails in the child, which aborts
    // (the harness sees it, not the machine).
    let dir = tempfile::tempdir().unwrap();
    let cornell = scene_arg("cornell-box.gltf");
    let out = nusselt_limited(
        &[
            "formfactors",
            &cornell,
            "-q",
            "--element-size",
            "0.005",
            "--memory-budget",
            "1000",
        ],
        dir.path(),
    );
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("memory allocation of") || out.status.code() != Some(1),
        "expected an abort under the limit, got: {stderr}"
    );
}

#[test]
fn direct_tiny_element_size_built_elements_before_the_matrix_budget() {
    let dir = tempfile::tempdir().unwrap();
    let cornell = scene_arg("cornell-box.gltf");
    let out = nusselt_limited(
        &[
            "solve",
            &cornell,
            "-o",
            "out",
            "-q",
            "--method",
            "direct",
            "--element-size",
            "1e-4",
        ],
        dir.path(),
    );
    assert_refused(
        &out,
        &[
            "--element-size 1e-4 makes 324272621 elements",
            "with their dense matrix and its factorisation",
            "over the memory budget of 2.00 GiB",
        ],
    );
    assert!(!dir.path().join("out").exists(), "nothing written");
}

#[test]
fn element_size_1e_300_asked_for_terabytes_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let cornell = scene_arg("cornell-box.gltf");
    for method in ["direct", "jacobi", "gauss-seidel"] {
        let out = nusselt_limited(
            &[
                "solve",
                &cornell,
                "-o",
                "out",
                "-q",
                "--method",
                method,
                "--element-size",
                "1e-300",
            ],
            dir.path(),
        );
        assert_refused(
            &out,
            &["--element-size 1e-300 makes", "need more than 16 EiB"],
        );
    }
}

#[test]
fn jacobi_tiny_element_size_built_elements_before_the_matrix_budget() {
    let dir = tempfile::tempdir().unwrap();
    let cornell = scene_arg("cornell-box.gltf");
    let out = nusselt_limited(
        &[
            "solve",
            &cornell,
            "-o",
            "out",
            "-q",
            "--method",
            "jacobi",
            "--element-size",
            "1e-4",
        ],
        dir.path(),
    );
    assert_refused(
        &out,
        &["--element-size 1e-4 makes 324272621 elements, which need"],
    );
}

#[test]
fn formfactors_tiny_element_size_built_elements_before_the_matrix_budget() {
    let dir = tempfile::tempdir().unwrap();
    let cornell = scene_arg("cornell-box.gltf");
    let out = nusselt_limited(
        &["formfactors", &cornell, "-q", "--element-size", "1e-4"],
        dir.path(),
    );
    assert_refused(&out, &["--element-size 1e-4 makes 324272621 elements"]);
}

#[test]
fn uniform_vertices_had_no_budget() {
    let dir = tempfile::tempdir().unwrap();
    let cornell = scene_arg("cornell-box.gltf");
    let out = nusselt_limited(
        &[
            "solve",
            &cornell,
            "-o",
            "out",
            "-q",
            "--mesh",
            "uniform",
            "--uniform-vertices",
            "1000000000",
        ],
        dir.path(),
    );
    assert_refused(
        &out,
        &[
            "--uniform-vertices 1000000000 puts up to",
            "over the memory budget of 2.00 GiB",
        ],
    );
    assert!(!dir.path().join("out").exists(), "nothing written");
}

/// 2¹⁵ indexed triangles: the 2 × 32² triangles of a 33 × 33 grid of
/// vertices in the unit square, listed 16 times (about 210 KB of u16
/// indices and positions).
fn grid_mesh(g: &mut Gltf, material: usize) -> usize {
    const N: u16 = 32;
    let positions: Vec<[f32; 3]> = (0..=N)
        .flat_map(|j| (0..=N).map(move |i| [f32::from(i) / 32.0, f32::from(j) / 32.0, 0.0]))
        .collect();
    let mut grid = Vec::new();
    for j in 0..N {
        for i in 0..N {
            let v = j * (N + 1) + i;
            grid.extend_from_slice(&[v, v + 1, v + N + 2, v, v + N + 2, v + N + 1]);
        }
    }
    let indices = grid.repeat(16);
    assert_eq!(indices.len(), 3 << 15);
    let pos = g.positions(&positions);
    let idx = g.indices(&indices);
    g.mesh(
        Some("Tiles"),
        vec![json!({"attributes": {"POSITION": pos}, "indices": idx, "material": material})],
    )
}

/// A binary tree of `depth` levels of distinct nodes (no shared child),
/// every leaf instancing `mesh`: 2^depth instances.
fn node_tree(g: &mut Gltf, mesh: usize, depth: u32) -> usize {
    if depth == 0 {
        return g.node(json!({"mesh": mesh}));
    }
    let a = node_tree(g, mesh, depth - 1);
    let b = node_tree(g, mesh, depth - 1);
    g.node(json!({"children": [a, b]}))
}

#[test]
fn instancing_bomb_was_refused_only_after_4_gb() {
    // 2¹⁵ triangles instanced by the 2⁹ leaves of a node tree, and the
    // light's 2: 2²⁴ + 2 triangles (8 GiB loaded) from a .glb of about
    // 250 KB.
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gltf::default();
    let light = g.light();
    let grey = g.grey();
    let mesh = grid_mesh(&mut g, grey);
    let top = node_tree(&mut g, mesh, 9);
    g.roots.push(top);
    let bytes = g.glb();
    assert!(bytes.len() < 300_000, "{} bytes", bytes.len());
    std::fs::write(dir.path().join("bomb.glb"), &bytes).unwrap();
    let out = nusselt_limited(&["solve", "bomb.glb", "-o", "out", "-q"], dir.path());
    assert_refused(
        &out,
        &[
            "bomb.glb: the node hierarchy instances 16777218 triangles",
            "most from mesh 'Tiles' (32768 triangles × 512 nodes)",
            "which need 8.00 GiB to load, over the memory budget of 2.00 GiB",
        ],
    );
    // Two levels more pass the triangle cap itself, whatever the budget.
    let top = node_tree(&mut g, mesh, 11);
    g.roots = vec![light, top];
    std::fs::write(dir.path().join("bomb.glb"), g.glb()).unwrap();
    let out = nusselt_limited(
        &[
            "solve",
            "bomb.glb",
            "-o",
            "out",
            "-q",
            "--memory-budget",
            "100",
        ],
        dir.path(),
    );
    assert_refused(
        &out,
        &[
            "instances 67108866 triangles",
            "which need 32.00 GiB to load, more than the limit of 33554432 triangles",
        ],
    );
}

/// An 8192 × 8192 PNG (a checkerboard of 64-texel squares) of about
/// 200 KB.
fn large_png() -> Vec<u8> {
    let img = image::GrayImage::from_fn(8192, 8192, |x, y| {
        image::Luma([if (x / 64 + y / 64) % 2 == 0 { 40 } else { 200 }])
    });
    let mut png = Vec::new();
    img.write_to(&mut Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    png
}

/// A lit scene with six quads, each textured by its own image entry, all
/// six entries naming `texture.png` (written next to the scene).
fn six_entries_one_png(dir: &Path) {
    std::fs::write(dir.join("texture.png"), large_png()).unwrap();
    let mut g = Gltf::default();
    g.light();
    for k in 0..6 {
        g.images
            .push(json!({"uri": "texture.png", "name": format!("entry {k}")}));
        g.textures.push(json!({"source": k}));
        let m = g.material(json!({"name": format!("Wall{k}"), "pbrMetallicRoughness": {
            "metallicFactor": 0.0, "baseColorTexture": {"index": k}}}));
        let mesh = g.quad_mesh(None, Some(m));
        g.root(json!({"mesh": mesh, "translation": [2.0 * k as f64, 0.0, 0.0]}));
    }
    std::fs::write(dir.join("textured.gltf"), g.embedded()).unwrap();
}

#[test]
fn texture_entries_sharing_one_png_were_each_decoded_to_f32() {
    // Six entries of one 8192² PNG: decoded once (64 MiB grey), kept as
    // 1024² means (12 MiB), where each entry used to take 0.8 GB of f32.
    let dir = tempfile::tempdir().unwrap();
    six_entries_one_png(dir.path());
    let out = nusselt_limited(
        &[
            "solve",
            "textured.gltf",
            "-o",
            "out",
            "-q",
            "--accuracy",
            "preview",
        ],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Within a budget below the decode, refused from the header, naming
    // the image and what it would need.
    let out = nusselt_limited(
        &[
            "solve",
            "textured.gltf",
            "-o",
            "out2",
            "-q",
            "--memory-budget",
            "0.05",
        ],
        dir.path(),
    );
    assert_refused(
        &out,
        &[
            "image 0 ('entry 0')",
            "8192×8192 texels need 76.0 MiB to decode, over the memory budget of 51.2 MiB",
        ],
    );
    assert!(!dir.path().join("out2").exists(), "nothing written");
}

/// A PNG's signature and `IHDR` chunk (`width` × `height`, 8-bit RGBA),
/// then the start of an `IDAT` chunk: all a decoder reads of its header.
fn png_head(width: u32, height: u32) -> Vec<u8> {
    fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let start = out.len();
        out.extend_from_slice(kind);
        out.extend_from_slice(data);
        let crc = crc32fast::hash(&out[start..]);
        out.extend_from_slice(&crc.to_be_bytes());
    }
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&width.to_be_bytes());
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[8, 6, 0, 0, 0]);
    chunk(&mut png, b"IHDR", &ihdr);
    png.extend_from_slice(&(1u32 << 30).to_be_bytes());
    png.extend_from_slice(b"IDAT");
    png
}

/// Bytes of the sparse files: 4 GiB, above the child's
/// address-space limit, so reading one whole aborts.
const SPARSE_FILE: u64 = 4 << 30;

/// `name` in `dir`: `head`, then zeros (a hole, no disk used) up to
/// [`SPARSE_FILE`] bytes.
fn sparse_file(dir: &Path, name: &str, head: &[u8]) {
    let path = dir.join(name);
    std::fs::write(&path, head).unwrap();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(SPARSE_FILE)
        .unwrap();
}

/// A lit quad whose material's `slot` (`baseColorTexture` or
/// `emissiveTexture`) is the image file `big.png`, named 'big'.
fn textured_by_file(dir: &Path, slot: &str) {
    let mut g = Gltf::default();
    g.light();
    g.images.push(json!({"uri": "big.png", "name": "big"}));
    g.textures.push(json!({"source": 0}));
    let m = if slot == "baseColorTexture" {
        g.material(json!({"name": "Wall", "pbrMetallicRoughness": {
            "metallicFactor": 0.0, "baseColorTexture": {"index": 0}}}))
    } else {
        g.material(json!({"name": "Wall", slot: {"index": 0}}))
    };
    let mesh = g.quad_mesh(None, Some(m));
    g.root(json!({"mesh": mesh}));
    std::fs::write(dir.join("scene.gltf"), g.embedded()).unwrap();
}

#[test]
fn image_file_was_read_whole_before_its_header_was_checked() {
    // A 4 GiB file with a PNG header of 8192² RGBA texels: refused from
    // its header (read through a buffer) for the decode's memory; it used
    // to be read whole first, which aborts under the limit.
    let dir = tempfile::tempdir().unwrap();
    textured_by_file(dir.path(), "baseColorTexture");
    sparse_file(dir.path(), "big.png", &png_head(8192, 8192));
    let out = nusselt_limited(
        &[
            "solve",
            "scene.gltf",
            "-o",
            "out",
            "-q",
            "--memory-budget",
            "0.25",
        ],
        dir.path(),
    );
    assert_refused(
        &out,
        &[
            "image 0 ('big')",
            "big.png",
            "8192×8192 texels need 268.0 MiB to decode, over the memory budget of 256.0 MiB",
        ],
    );
    assert!(!dir.path().join("out").exists(), "nothing written");
    // A small header in the same 4 GiB: refused for the file's own size.
    sparse_file(dir.path(), "big.png", &png_head(16, 16));
    let out = nusselt_limited(&["solve", "scene.gltf", "-o", "out", "-q"], dir.path());
    assert_refused(
        &out,
        &[
            "image 0 ('big')",
            "the file has 4.00 GiB, over the memory budget of 2.00 GiB",
        ],
    );
    assert!(!dir.path().join("out").exists(), "nothing written");
}

#[test]
fn jpeg_file_was_read_whole_to_find_its_header() {
    // A JPEG decoder reads its whole input for the header: the file's
    // size is checked first.
    let dir = tempfile::tempdir().unwrap();
    textured_by_file(dir.path(), "baseColorTexture");
    sparse_file(dir.path(), "big.png", b"\xff\xd8\xff\xe0\x00\x10JFIF\x00");
    let out = nusselt_limited(&["solve", "scene.gltf", "-o", "out", "-q"], dir.path());
    assert_refused(
        &out,
        &[
            "image 0 ('big')",
            "the file has 4.00 GiB, over the memory budget of 2.00 GiB",
        ],
    );
}

#[test]
fn image_file_kept_for_the_bake_was_read_whole_unchecked() {
    // An emissive texture with the default zero factor is never decoded,
    // but the bake keeps its bytes: its size is checked before reading.
    let dir = tempfile::tempdir().unwrap();
    textured_by_file(dir.path(), "emissiveTexture");
    sparse_file(dir.path(), "big.png", &png_head(16, 16));
    let out = nusselt_limited(&["solve", "scene.gltf", "-o", "out", "-q"], dir.path());
    assert_refused(
        &out,
        &[
            "image 0 ('big')",
            "the file has 4.00 GiB, over the memory budget of 2.00 GiB",
        ],
    );
}

#[test]
fn render_size_was_not_checked_against_the_memory_budget() {
    // 16384² passes the side cap; its buffers (128 bytes a pixel) do not
    // fit the default budget, and are refused before the solve.
    let dir = tempfile::tempdir().unwrap();
    let cornell = scene_arg("cornell-box.gltf");
    let solve = |extra: &[&str]| {
        let mut args = vec!["solve", &cornell, "-o", "out", "-q"];
        args.extend_from_slice(extra);
        nusselt_limited(&args, dir.path())
    };
    let out = solve(&["--width", "16384", "--height", "16384"]);
    assert_refused(
        &out,
        &[
            "the 16384 × 16384 render (--width 16384 --height 16384) needs 32.00 GiB, \
             over the memory budget of 2.00 GiB",
        ],
    );
    assert!(!dir.path().join("out").exists(), "nothing written");
    // The classic methods check it too, after their own budget.
    let out = solve(&["--method", "jacobi", "--width", "16384"]);
    assert_refused(
        &out,
        &["--width 16384 and the camera's aspect ratio) needs 32.00 GiB"],
    );
    // Past the side cap: refused by it.
    let out = solve(&["--width", "1000000", "--height", "1000000"]);
    assert_refused(&out, &["each side must be between 1 and 16384"]);
    // Snapshots hold a frame each, lightmaps their atlases.
    let out = solve(&[
        "--width",
        "2048",
        "--height",
        "2048",
        "--snapshots",
        &(1..=100)
            .map(|k| k.to_string())
            .collect::<Vec<_>>()
            .join(","),
    ]);
    assert_refused(
        &out,
        &[
            "the 2048 × 2048 render (--width 2048 --height 2048) needs 512.0 MiB, \
             its 100 snapshots (--snapshots) 4.69 GiB: 5.19 GiB in all, \
             over the memory budget of 2.00 GiB",
        ],
    );
    let out = solve(&["--lightmap", "16384"]);
    assert_refused(
        &out,
        &["the lightmaps (--lightmap 16384) 24.00 GiB: 24.03 GiB in all"],
    );
    assert!(!dir.path().join("out").exists(), "nothing written");
}

#[test]
fn render_and_reference_sizes_were_not_checked_against_a_budget() {
    let dir = tempfile::tempdir().unwrap();
    let cornell = scene_arg("cornell-box.gltf");
    let out = nusselt_limited(
        &[
            "solve",
            &cornell,
            "-o",
            "out",
            "-q",
            "--accuracy",
            "preview",
            "--width",
            "8",
            "--spp",
            "1",
        ],
        dir.path(),
    );
    assert!(out.status.success());
    let big = ["--width", "16384", "--height", "16384"];
    let mut render = vec!["render", "out/solution.exr", "-q", "-o", "big.exr"];
    render.extend_from_slice(&big);
    let out = nusselt_limited(&render, dir.path());
    assert_refused(
        &out,
        &[
            "the 16384 × 16384 render (--width 16384 --height 16384) needs 32.00 GiB, \
           over the memory budget of 2.00 GiB",
        ],
    );
    let mut reference = vec!["reference", &cornell, "-q", "-o", "big.exr"];
    reference.extend_from_slice(&big);
    let out = nusselt_limited(&reference, dir.path());
    assert_refused(
        &out,
        &["needs 32.00 GiB, over the memory budget of 2.00 GiB"],
    );
    // The budget is the flag's.
    render.extend_from_slice(&["--memory-budget", "0.0001"]);
    render[6] = "64";
    render[8] = "64";
    let out = nusselt_limited(&render, dir.path());
    assert_refused(
        &out,
        &[
            "the 64 × 64 render (--width 64 --height 64) needs 0.5 MiB, \
           over the memory budget of 0.1 MiB",
        ],
    );
    assert!(!dir.path().join("big.exr").exists(), "nothing written");
}

#[test]
fn buffer_file_was_read_whole_unchecked() {
    // A 4 GiB external buffer (sparse) declared as 48 bytes: `gltf`
    // reads a buffer file whole, so its size is checked first.
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gltf::default();
    g.light();
    let json = g.json(json!({"byteLength": g.bin.len(), "uri": "big.bin"}));
    std::fs::write(dir.path().join("scene.gltf"), json.to_string()).unwrap();
    sparse_file(dir.path(), "big.bin", &g.bin);
    let out = nusselt_limited(&["solve", "scene.gltf", "-o", "out", "-q"], dir.path());
    assert_refused(
        &out,
        &[
            "buffer 0:",
            "big.bin' has 4.00 GiB, over the memory budget of 2.00 GiB",
        ],
    );
    assert!(!dir.path().join("out").exists(), "nothing written");
}
