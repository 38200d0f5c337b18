//! The path-traced reference of a scene, cached on disk between runs: the
//! one place that renders a lab reference and knows its files.
//!
//! Owns: the key of a reference ([`ReferenceKey`]: scene name, view, paths
//! per pixel, seed), rendering it ([`render`]), and the two on-disk
//! layouts ([`Naming`]) its callers use:
//!
//! - [`Naming::KeyInFileName`] (the failure table): many references share
//!   one folder, each as `<scene>-<w>x<h>-<spp>spp-seed<seed>.exr` and
//!   `.noise.exr`; the key is the file name, so an unreadable file is simply
//!   a miss.
//! - [`Naming::Sidecars`] (`nusselt study`): one reference per folder, as
//!   `reference.exr`, `reference.noise.exr`, `reference.json` (its
//!   [`ReferenceStats`]) and `reference-view.json` (its [`View`]); the key is
//!   read back from the two JSON sidecars, and a reference whose sidecars
//!   match but whose images cannot be read is an error, not a miss.
//!
//! Invariants:
//! - A cached reference is used only when every part of its key matches;
//!   otherwise it is rendered again (never patched up).
//! - The files and their contents are exactly what each caller wrote
//!   before this module existed, so old caches stay valid.
//! - Nothing is written here behind the caller's back: [`ReferenceCache::files`]
//!   returns the bytes to stage, [`ReferenceCache::write`] writes them
//!   atomically, and the caller picks which.

use std::path::{Path, PathBuf};

use crate::error::Result;
use crate::output;
use crate::output::exr::{ImageInfo, Quantity};
use crate::reference::{self, ReferenceImage, ReferenceSettings, ReferenceStats};
use crate::render::frame::Frame;
use crate::render::view::View;
use crate::scene::Scene;
use crate::util::progress::Progress;

/// What a cached reference must match to be reused.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ReferenceKey<'a> {
    /// The scene's name (its file stem, or the name the caller gives it).
    pub scene: &'a str,
    pub view: &'a View,
    /// Paths per pixel asked for (rendered with at least 2).
    pub spp: u32,
    pub seed: u64,
}

impl ReferenceKey<'_> {
    /// The path tracer's settings for this key: at least 2 paths per pixel
    /// (the noise estimate needs two), unlimited bounces.
    fn settings(&self) -> ReferenceSettings {
        ReferenceSettings {
            samples_per_pixel: self.spp.max(2),
            seed: self.seed,
            max_bounces: None,
        }
    }
}

/// How a cache names its files and where it keeps the key.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Naming {
    /// `<scene>-<w>x<h>-<spp>spp-seed<seed>.exr` and `.noise.exr`.
    KeyInFileName,
    /// `reference.exr`, `reference.noise.exr`, `reference.json`,
    /// `reference-view.json`.
    Sidecars,
}

/// The file stem of [`Naming::Sidecars`].
const SIDECAR_STEM: &str = "reference";

/// A folder of cached references, named one way.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ReferenceCache<'a> {
    pub dir: &'a Path,
    pub naming: Naming,
}

/// One file of a cached reference, before encoding.
enum Content<'r> {
    Exr(&'r Frame, ImageInfo<'r>),
    Stats(&'r ReferenceStats),
    View(&'r View),
}

impl Content<'_> {
    fn encode(&self) -> Result<Vec<u8>> {
        match self {
            Content::Exr(frame, info) => output::exr::encode_image(frame, info),
            Content::Stats(stats) => output::write_json(stats),
            Content::View(view) => output::write_json(view),
        }
    }
}

impl ReferenceCache<'_> {
    /// The file stem of the reference of `key`.
    fn stem(&self, key: &ReferenceKey) -> String {
        match self.naming {
            Naming::KeyInFileName => format!(
                "{}-{}x{}-{}spp-seed{}",
                key.scene, key.view.width, key.view.height, key.spp, key.seed
            ),
            Naming::Sidecars => SIDECAR_STEM.to_string(),
        }
    }

    /// Where the reference image of `key` is (or would be) cached.
    pub fn image_path(&self, key: &ReferenceKey) -> PathBuf {
        self.dir.join(format!("{}.exr", self.stem(key)))
    }

    /// The cached reference image and its noise image for `key`, or `None`
    /// when the folder holds none for this key (module doc: which failures
    /// are misses and which are errors).
    pub fn load(&self, key: &ReferenceKey) -> Result<Option<(Frame, Frame)>> {
        let stem = self.stem(key);
        let image_path = self.dir.join(format!("{stem}.exr"));
        let noise_path = self.dir.join(format!("{stem}.noise.exr"));
        match self.naming {
            Naming::KeyInFileName => {
                let Ok(image) = output::exr::read_image(&image_path) else {
                    return Ok(None);
                };
                let Ok(noise) = output::exr::read_image(&noise_path) else {
                    return Ok(None);
                };
                Ok(Some((image, noise)))
            }
            Naming::Sidecars => {
                if !self.sidecars_match(&stem, key) {
                    return Ok(None);
                }
                let image = output::exr::read_image(&image_path)?;
                let noise = output::exr::read_image(&noise_path)?;
                Ok(Some((image, noise)))
            }
        }
    }

    /// Whether the JSON sidecars of `stem` were written for `key`.
    fn sidecars_match(&self, stem: &str, key: &ReferenceKey) -> bool {
        let Ok(bytes) = std::fs::read(self.dir.join(format!("{stem}.json"))) else {
            return false;
        };
        let Ok(stats) = serde_json::from_slice::<ReferenceStats>(&bytes) else {
            return false;
        };
        let cached_view = std::fs::read(self.dir.join(format!("{stem}-view.json")))
            .ok()
            .and_then(|b| serde_json::from_slice::<View>(&b).ok());
        stats.scene == key.scene
            && stats.spp == key.spp
            && stats.seed == key.seed
            && cached_view.as_ref() == Some(key.view)
    }

    /// The files caching `rendered` (the reference of `key`), file names
    /// relative to the folder, in writing order.
    fn contents<'r>(
        &self,
        key: &'r ReferenceKey,
        rendered: &'r ReferenceImage,
    ) -> Vec<(String, Content<'r>)> {
        let stem = self.stem(key);
        let info = |quantity| {
            ImageInfo::new(quantity)
                .scene(key.scene)
                .view(Some(key.view))
        };
        let mut out = vec![
            (
                format!("{stem}.exr"),
                Content::Exr(&rendered.image, info(Quantity::Radiance)),
            ),
            (
                format!("{stem}.noise.exr"),
                Content::Exr(&rendered.noise, info(Quantity::RadianceStandardError)),
            ),
        ];
        if self.naming == Naming::Sidecars {
            out.push((format!("{stem}.json"), Content::Stats(&rendered.stats)));
            out.push((format!("{stem}-view.json"), Content::View(key.view)));
        }
        out
    }

    /// The encoded files caching `rendered`, (name relative to the folder,
    /// bytes), for the caller to stage with its other outputs.
    pub fn files(
        &self,
        key: &ReferenceKey,
        rendered: &ReferenceImage,
    ) -> Result<Vec<(String, Vec<u8>)>> {
        self.contents(key, rendered)
            .into_iter()
            .map(|(name, content)| Ok((name, content.encode()?)))
            .collect()
    }

    /// Writes the files caching `rendered` into the folder now, each
    /// atomically, one after the other.
    pub fn write(&self, key: &ReferenceKey, rendered: &ReferenceImage) -> Result<()> {
        for (name, content) in self.contents(key, rendered) {
            output::write_atomic(&self.dir.join(name), &content.encode()?)?;
        }
        Ok(())
    }
}

/// Path traces the reference of `key` on `scene`, its stats naming
/// `key.scene`.
pub(crate) fn render(
    scene: &Scene,
    key: &ReferenceKey,
    progress: &Progress,
) -> Result<ReferenceImage> {
    let mut rendered = reference::render_reference(scene, key.view, &key.settings(), progress)?;
    rendered.stats.scene = key.scene.to_string();
    Ok(rendered)
}
