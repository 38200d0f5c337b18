//! The bundled-scene generator behind `cargo run --example gen-scenes`.
//!
//! Owns the scene definitions (`cornell`, `goral`, `penumbra`,
//! `two_squares`, `interior`), the stress scenes of `scenes/stress/`
//! (`stress`), their encoding to glTF (`encode`) and the scenes' README
//! (`readme`, covering both). Invariant: generation is a pure function of this code, so the
//! files in `scenes/` are byte-identical on every run; the test
//! `scenes::bundled_scenes_are_up_to_date` regenerates them and compares.

pub mod cornell;
pub mod encode;
pub mod goral;
pub mod interior;
pub mod lattice;
pub mod model;
pub mod penumbra;
pub mod readme;
pub mod shapes;
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
    ]
}

/// Folder of the stress scenes, relative to the bundled scenes' folder.
pub const STRESS_DIR: &str = "stress";

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
    let mut files = Vec::new();
    for scene in &scenes {
        push_scene(&mut files, "", scene)?;
    }
    for s in &stress {
        push_scene(&mut files, &format!("{STRESS_DIR}/"), &s.scene)?;
    }
    files.push((
        "README.md".to_owned(),
        readme::readme(&scenes, &stress)?.into_bytes(),
    ));
    Ok(files)
}

/// Writes every file of [`render_all`] into `dir` (created if missing) and
/// returns the paths written.
pub fn write_all(dir: &Path) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut written = Vec::new();
    for (name, bytes) in render_all()? {
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
