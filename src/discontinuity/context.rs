//! The read-only state of one run of `discontinuity_segments`, built once
//! and shared by every phase and thread.
//!
//! Owns: [`Context`] (the scene and its BVH, the settings, the padded scene
//! box, the occluder graph, the receivers, the significant luminaires and
//! the mean exitance), the plane tolerance of a run and the significance
//! weight of a point.
//!
//! Invariants: nothing in a `Context` changes after [`Context::new`]; the
//! phases only read it, so they can run in parallel in any order and the
//! result depends only on the order in which their outputs are collected.

use glam::DVec3;

use super::clip::Bounds;
use super::luminaires::{self, Luminaire};
use super::occluders::Occluders;
use super::planes::ReceiverIndex;
use super::receivers::Receiver;
use super::{CONTACT_TOL, DiscontinuitySettings, PLANE_TOL};
use crate::formfactor::form_factor_point_polygon;
use crate::scene::Scene;
use crate::visibility::TriangleBvh;

/// Everything the phases read.
pub(super) struct Context<'a> {
    pub(super) scene: &'a Scene,
    /// Holds `scene.triangles`.
    pub(super) bvh: &'a TriangleBvh,
    pub(super) settings: &'a DiscontinuitySettings,
    pub(super) diagonal: f64,
    /// The scene box, padded by the contact tolerance.
    pub(super) bounds: Bounds,
    pub(super) occluders: Occluders,
    /// One per scene patch, in patch order.
    pub(super) receivers: Vec<Receiver>,
    /// The receivers grouped by plane, for the contact searches.
    pub(super) index: ReceiverIndex,
    /// The significant luminaires, ordered by lowest patch.
    pub(super) luminaires: Vec<Luminaire>,
    /// Scalar mean exitance over all emitting area.
    pub(super) mean_exitance: f64,
}

impl<'a> Context<'a> {
    /// Welds the occluders, projects the receivers and groups and selects
    /// the luminaires of `scene`.
    pub(super) fn new(
        scene: &'a Scene,
        bvh: &'a TriangleBvh,
        settings: &'a DiscontinuitySettings,
    ) -> Context<'a> {
        let diagonal = scene.diagonal();
        let pad = DVec3::splat(CONTACT_TOL * diagonal);
        let bounds = Bounds {
            lo: scene.bounds.0 - pad,
            hi: scene.bounds.1 + pad,
        };
        let occluders = Occluders::weld(scene, PLANE_TOL * diagonal);
        let receivers: Vec<Receiver> = scene
            .patches
            .iter()
            .map(|p| Receiver::new(p, pad))
            .collect();
        let index = ReceiverIndex::new(&receivers, &bounds, diagonal);
        let mean_exitance = luminaires::mean_exitance(scene);
        let luminaires =
            luminaires::significant(scene, diagonal, settings.min_emitter_fraction, &receivers);
        Context {
            scene,
            bvh,
            settings,
            diagonal,
            bounds,
            occluders,
            receivers,
            index,
            luminaires,
            mean_exitance,
        }
    }

    /// The sidedness tolerance for planes, as a length.
    pub(super) fn tol(&self) -> f64 {
        PLANE_TOL * self.diagonal
    }

    /// Unoccluded irradiance at `x` on receiver `r` from luminaire `l`, over
    /// the mean exitance; 0 without any light.
    pub(super) fn weight(&self, l: &Luminaire, r: u32, x: DVec3) -> f64 {
        if !(self.mean_exitance > 0.0) {
            return 0.0;
        }
        let n = self.receivers[r as usize].normal;
        match l.light {
            Some(k) => {
                let light = &self.scene.lights.punctual[k];
                light
                    .incident(x, n, self.scene.far())
                    .map_or(0.0, |i| luminaires::scalar(i.irradiance))
                    / self.mean_exitance
            }
            None => form_factor_point_polygon(x, n, &l.polygon) * l.exitance / self.mean_exitance,
        }
    }
}
