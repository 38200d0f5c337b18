//! The bundled-scene generator behind `cargo run --example gen-scenes`.
//!
//! Owns the scene definitions (`cornell`, `goral`, `penumbra`,
//! `two_squares`, `interior`, and `spot_room` and `courtyard`, which are lit
//! by `KHR_lights_punctual` lights instead of emitters), the stress scenes
//! of `scenes/stress/` (`stress`), the scale-up family of `scenes/scale/`
//! (`scale`; only its 10⁴-triangle member is bundled, the others are
//! written on demand by [`write_scale`]), their encoding to glTF (`encode`)
//! and the scenes' README (`readme`, covering all three). Invariant:
//! generation is a pure function of this code, so the files in `scenes/`
//! are byte-identical on every run; the test
//! `scenes::bundled_scenes_are_up_to_date` regenerates them and compares.

pub mod cornell;
pub mod courtyard;
pub mod encode;
pub mod fan;
pub mod goral;
pub mod hard;
pub mod interior;
pub mod lattice;
pub mod model;
pub mod penumbra;
pub mod readme;
pub mod scale;
pub mod shapes;
pub mod spot_room;
pub mod stress;
pub mod two_squares;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use model::{BufferStorage, SceneDef};

/// Every bundled scene, in README order.
pub fn scenes() -> Vec<SceneDef> {
    vec![
        cornell::scene(),
        goral::scene(),
        penumbra::scene(),
        interior::scene(),
        two_squares::scene(),
        spot_room::scene(),
        courtyard::scene(),
    ]
}

/// Folder of the stress scenes, relative to the bundled scenes' folder.
pub const STRESS_DIR: &str = "stress";

/// Folder of the hard interiors, relative to the bundled scenes' folder.
pub const HARD_DIR: &str = "hard";

/// Folder of the scale-up scenes, relative to the bundled scenes' folder.
pub const SCALE_DIR: &str = "scale";

/// Target triangle count of the bundled member of the scale-up family.
pub const BUNDLED_SCALE: usize = 10_000;

/// Targets of the scale-up family that the README describes.
pub const SCALE_TARGETS: [usize; 3] = [10_000, 100_000, 1_000_000];

/// Appends the files of `scene` (its `.gltf`, and its `.bin` if external),
/// named relative to the scenes' folder with the prefix `dir`.
fn push_scene(files: &mut Vec<(String, Vec<u8>)>, dir: &str, scene: &SceneDef) -> Result<()> {
    let (root, bin) = encode::encode(scene).with_context(|| format!("scene {}", scene.stem))?;
    let mut json = serde_json::to_string_pretty(&root)?;
    json.push('\n');
    files.push((format!("{dir}{}.gltf", scene.stem), json.into_bytes()));
    if scene.storage == BufferStorage::External {
        files.push((format!("{dir}{}.bin", scene.stem), bin));
    }
    Ok(())
}

/// The files of every scene (the stress scenes under [`STRESS_DIR`]) and
/// the README, as (path relative to the scenes' folder, bytes), in a fixed
/// order.
pub fn render_all() -> Result<Vec<(String, Vec<u8>)>> {
    let scenes = scenes();
    let stress = stress::scenes();
    let hard = hard::scenes();
    let office = scale::scene(BUNDLED_SCALE);
    let mut files = Vec::new();
    for scene in &scenes {
        push_scene(&mut files, "", scene)?;
    }
    for s in &stress {
        push_scene(&mut files, &format!("{STRESS_DIR}/"), &s.scene)?;
    }
    for h in &hard {
        push_scene(&mut files, &format!("{HARD_DIR}/"), &h.scene)?;
    }
    push_scene(&mut files, &format!("{SCALE_DIR}/"), &office)?;
    files.push((
        "README.md".to_owned(),
        readme::readme(&scenes, &stress, &hard, &office)?.into_bytes(),
    ));
    Ok(files)
}

/// Writes every file of [`render_all`] into `dir` (created if missing) and
/// returns the paths written.
pub fn write_all(dir: &Path) -> Result<Vec<PathBuf>> {
    write_files(dir, render_all()?)
}

/// Writes the scale-up scene for `target` triangles into `dir` (created if
/// missing), as `office-<size>.gltf` and `.bin`, and returns the paths
/// written and the scene's triangle count.
pub fn write_scale(dir: &Path, target: usize) -> Result<(Vec<PathBuf>, usize)> {
    let scene = scale::scene(target);
    let mut files = Vec::new();
    push_scene(&mut files, "", &scene)?;
    Ok((write_files(dir, files)?, model::triangle_count(&scene)))
}

/// Writes the fan benchmark scene of `n` slivers into `dir` (created if
/// missing), as `fan-<n>.gltf` and `.bin`, and returns the paths written.
pub fn write_fan(dir: &Path, n: usize) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    push_scene(&mut files, "", &fan::scene(n))?;
    write_files(dir, files)
}

/// Writes `files` (path relative to `dir`, bytes) into `dir`.
fn write_files(dir: &Path, files: Vec<(String, Vec<u8>)>) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut written = Vec::new();
    for (name, bytes) in files {
        let path = dir.join(&name);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent)
                .with_context(|| format!("creating {}", parent.display()))?;
        }
        std::fs::write(&path, bytes).with_context(|| format!("writing {}", path.display()))?;
        written.push(path);
    }
    Ok(written)
}
