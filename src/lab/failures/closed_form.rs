//! The closed forms of the stress scenes: exact powers the table measures
//! each method's power against.
//!
//! Owns which scene (by file stem) has which closed form and the numeric
//! integral the flat-receiver forms need ([`receiver_integrals`]).
//! Invariant: a closed form is only given when the scene has the shape its
//! name promises (checked here, not trusted); otherwise there is none and
//! the reference image is the only yardstick.

use glam::DVec3;

use crate::formfactor::form_factor_point_polygon;
use crate::lab::failures::mean3;
use crate::scene::{Patch, Scene, Shape};

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
    /// The power the value is of.
    pub quantity: Quantity,
    /// The exact value, watts (channel mean).
    pub watts: f64,
    /// Where the value comes from, for the table.
    pub why: &'static str,
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
}
