//! Lights that are not surfaces: `KHR_lights_punctual` point, spot and
//! directional lights, and the sky around an open scene.
//!
//! Owns: [`PunctualLight`], [`Sky`], [`Lights`] and the unoccluded light
//! each delivers to a surface point ([`PunctualLight::incident`],
//! [`Sky::radiance`]). Visibility is the caller's (`crate::illumination`).
//!
//! Units, as the contract states them: a point light of intensity I (the
//! glTF "candela", here in the emitters' radiometric units) gives the
//! irradiance I cos θ / r² at distance r, in the units of the emitters'
//! exitance E; a spot light the same times the glTF spec's smooth cone
//! falloff; a directional light of intensity E (the glTF "lux") gives
//! E cos θ. A uniform sky of radiance L gives π L on an open plane.
//!
//! Invariants: intensities and radiances are finite and non-negative per
//! channel; directions are unit; a spot's cosines satisfy
//! 1 ≥ cos_inner > cos_outer ≥ 0; a range is positive; an environment
//! map has width × height finite, non-negative texels.

use std::f64::consts::PI;

use glam::DVec3;

/// What kind of punctual light, with its kind's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    /// Light in every direction from `position`.
    Point,
    /// Light in a cone about `direction` from `position`: full up to the
    /// inner angle, none beyond the outer, the glTF spec's smooth
    /// (squared linear-in-cosine) falloff between.
    Spot {
        /// cos(innerConeAngle).
        cos_inner: f64,
        /// cos(outerConeAngle).
        cos_outer: f64,
    },
    /// Parallel light along `direction` from infinitely far away.
    Directional,
}

/// One `KHR_lights_punctual` light placed in the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct PunctualLight {
    /// The light's name, else `<kind> light <index>`.
    pub name: String,
    /// Point, spot or directional.
    pub kind: LightKind,
    /// World position (unused by a directional light).
    pub position: DVec3,
    /// Unit direction the light travels (spot, directional): the node's
    /// local −z in world space.
    pub direction: DVec3,
    /// colour × intensity per channel: radiant intensity (point, spot) or
    /// irradiance on a surface facing the light (directional).
    pub intensity: DVec3,
    /// Point and spot: the distance beyond which the light is zero (glTF
    /// `range`), with the spec's smooth window before it.
    pub range: Option<f64>,
}

/// The light a punctual light would deliver at a point if nothing were in
/// the way.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Incident {
    /// Irradiance on the surface (cos θ included).
    pub irradiance: DVec3,
    /// Where a shadow ray must reach to see the light: the light's position,
    /// or, for a directional light, a point `far` away toward it.
    pub toward: DVec3,
}

impl PunctualLight {
    /// The unoccluded light at `x` on a surface of unit normal `n` (lit on
    /// its front only); `far` is a distance beyond the whole scene, for a
    /// directional light's shadow ray. `None` when it gets none.
    pub fn incident(&self, x: DVec3, n: DVec3, far: f64) -> Option<Incident> {
        let (irradiance, toward) = match self.kind {
            LightKind::Directional => {
                let cos = -n.dot(self.direction);
                (self.intensity * cos, x - far * self.direction)
            }
            LightKind::Point | LightKind::Spot { .. } => {
                let to_light = self.position - x;
                let r2 = to_light.length_squared();
                if !(r2 > 0.0) {
                    return None;
                }
                let r = r2.sqrt();
                let wi = to_light / r;
                let cos = n.dot(wi);
                let mut scale = cos / r2 * range_window(r, self.range);
                if let LightKind::Spot {
                    cos_inner,
                    cos_outer,
                } = self.kind
                {
                    scale *= cone_falloff(-wi.dot(self.direction), cos_inner, cos_outer);
                }
                (self.intensity * scale, self.position)
            }
        };
        (irradiance.max_element() > 0.0 && irradiance.is_finite()).then_some(Incident {
            irradiance: irradiance.max(DVec3::ZERO),
            toward,
        })
    }

    /// The power the light sends out (W per channel), for the scene's
    /// scale: 4π I for a point light, the cone's integral for a spot (both
    /// ignoring `range`), and for a directional light E times the area a
    /// box of `extent` (its side lengths) shows it.
    pub fn power(&self, extent: DVec3) -> DVec3 {
        match self.kind {
            LightKind::Point => 4.0 * PI * self.intensity,
            LightKind::Spot {
                cos_inner,
                cos_outer,
            } => {
                // ∫ falloff dω = 2π ∫ f(c) dc over c = cos ψ in [cos_outer, 1]:
                // 1 over [cos_inner, 1], ((c − c_o)/(c_i − c_o))² between.
                let full = 1.0 - cos_inner;
                let ramp = (cos_inner - cos_outer) / 3.0;
                2.0 * PI * (full + ramp) * self.intensity
            }
            LightKind::Directional => {
                let d = self.direction.abs();
                let shown = d.x * extent.y * extent.z
                    + d.y * extent.x * extent.z
                    + d.z * extent.x * extent.y;
                self.intensity * shown
            }
        }
    }

    /// "point", "spot" or "directional".
    pub fn kind_name(&self) -> &'static str {
        match self.kind {
            LightKind::Point => "point",
            LightKind::Spot { .. } => "spot",
            LightKind::Directional => "directional",
        }
    }
}

/// The glTF spec's recommended window for `range`: 1 − (r / range)⁴,
/// clamped to [0, 1]; 1 without a range.
pub fn range_window(r: f64, range: Option<f64>) -> f64 {
    match range {
        Some(range) => (1.0 - (r / range).powi(4)).clamp(0.0, 1.0),
        None => 1.0,
    }
}

/// The glTF spec's spot falloff at cos ψ = `c` from the axis: the square of
/// (c − cos_outer) / (cos_inner − cos_outer), clamped to [0, 1].
pub fn cone_falloff(c: f64, cos_inner: f64, cos_outer: f64) -> f64 {
    let scale = 1.0 / (cos_inner - cos_outer).max(1e-3);
    let t = ((c - cos_outer) * scale).clamp(0.0, 1.0);
    t * t
}

/// An equirectangular environment: row 0 is the zenith (+y), the last row
/// the nadir; column u at azimuth φ = 2π (u + ½) / width − π measured from
/// −z toward +x, so the image's centre looks along −z.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentMap {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Radiance per texel (W·m⁻²·sr⁻¹), row by row from the top.
    pub texels: Vec<[f32; 3]>,
}

impl EnvironmentMap {
    /// Radiance toward unit `d`, bilinear between texel centres, wrapping
    /// in azimuth.
    pub fn radiance(&self, d: DVec3) -> DVec3 {
        let (w, h) = (self.width as usize, self.height as usize);
        let phi = d.x.atan2(-d.z); // −π..π, 0 along −z
        let theta = d.y.clamp(-1.0, 1.0).acos(); // 0 at the zenith
        let u = (phi / (2.0 * PI) + 0.5) * w as f64 - 0.5;
        let v = (theta / PI * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
        let (u0, v0) = (u.floor(), v.floor());
        let (fu, fv) = (u - u0, v - v0);
        let col = |k: f64| (k as i64).rem_euclid(w as i64) as usize;
        let row = |k: f64| (k as usize).min(h - 1);
        let texel = |c: usize, r: usize| DVec3::from(self.texels[r * w + c].map(f64::from));
        let (c0, c1, r0, r1) = (col(u0), col(u0 + 1.0), row(v0), row(v0 + 1.0));
        (1.0 - fv) * ((1.0 - fu) * texel(c0, r0) + fu * texel(c1, r0))
            + fv * ((1.0 - fu) * texel(c0, r1) + fu * texel(c1, r1))
    }

    /// The mean radiance over the sphere (solid-angle weighted).
    pub fn mean(&self) -> DVec3 {
        let (w, h) = (self.width as usize, self.height as usize);
        let mut sum = DVec3::ZERO;
        let mut weight = 0.0;
        for r in 0..h {
            let s = ((r as f64 + 0.5) / h as f64 * PI).sin();
            for c in 0..w {
                sum += s * DVec3::from(self.texels[r * w + c].map(f64::from));
                weight += s;
            }
        }
        sum / weight
    }
}

/// What the world outside sends into an open scene; it also absorbs every
/// ray that leaves.
#[derive(Clone, Debug, PartialEq)]
pub enum Sky {
    /// The same radiance from every direction.
    Uniform(DVec3),
    /// Radiance by direction.
    Map(EnvironmentMap),
}

impl Sky {
    /// Radiance arriving from the sky along −`d` (`d` unit, pointing into
    /// the sky).
    pub fn radiance(&self, d: DVec3) -> DVec3 {
        match self {
            Sky::Uniform(l) => *l,
            Sky::Map(map) => map.radiance(d),
        }
    }

    /// The mean radiance over the sphere.
    pub fn mean(&self) -> DVec3 {
        match self {
            Sky::Uniform(l) => *l,
            Sky::Map(map) => map.mean(),
        }
    }
}

/// Every light of a scene that is not an emitting surface.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Lights {
    /// The placed `KHR_lights_punctual` lights, in node order.
    pub punctual: Vec<PunctualLight>,
    /// The sky, when the run gives one.
    pub sky: Option<Sky>,
}

impl Lights {
    /// True when there is no punctual light and no sky.
    pub fn is_empty(&self) -> bool {
        self.punctual.is_empty() && self.sky.is_none()
    }

    /// A bound on the power these lights bring into a scene whose bounding
    /// box has side lengths `extent`: the punctual lights' output
    /// ([`PunctualLight::power`]) and, for the sky, π L̄ over half the
    /// box's surface (what a box fully open to a sky of mean radiance L̄
    /// would receive from above and the sides). A scale for thresholds,
    /// not the report's figure (the solver measures what arrives).
    pub fn power_bound(&self, extent: DVec3) -> DVec3 {
        let surface = 2.0 * (extent.x * extent.y + extent.y * extent.z + extent.z * extent.x);
        let sky = self
            .sky
            .as_ref()
            .map_or(DVec3::ZERO, |s| PI * s.mean() * 0.5 * surface);
        self.punctual.iter().map(|l| l.power(extent)).sum::<DVec3>() + sky
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn light(kind: LightKind) -> PunctualLight {
        PunctualLight {
            name: "l".into(),
            kind,
            position: DVec3::new(0.0, 2.0, 0.0),
            direction: DVec3::NEG_Y,
            intensity: DVec3::new(10.0, 5.0, 1.0),
            range: None,
        }
    }

    #[test]
    fn a_point_light_gives_i_cos_over_r_squared() {
        let l = light(LightKind::Point);
        let x = DVec3::new(1.5, 0.0, 0.0);
        let got = l.incident(x, DVec3::Y, 100.0).unwrap();
        let r2 = 1.5f64 * 1.5 + 4.0;
        let cos = 2.0 / r2.sqrt();
        let want = l.intensity * cos / r2;
        assert!((got.irradiance - want).abs().max_element() < 1e-12);
        assert_eq!(got.toward, l.position);
        // From behind, nothing.
        assert!(l.incident(x, DVec3::NEG_Y, 100.0).is_none());
    }

    #[test]
    fn range_and_cone_follow_the_spec() {
        assert_eq!(range_window(0.5, Some(1.0)), 1.0 - 0.0625);
        assert_eq!(range_window(2.0, Some(1.0)), 0.0);
        assert_eq!(range_window(7.0, None), 1.0);
        let (ci, co) = (0.9, 0.7);
        assert_eq!(cone_falloff(0.95, ci, co), 1.0);
        assert_eq!(cone_falloff(0.6, ci, co), 0.0);
        assert!((cone_falloff(0.8, ci, co) - 0.25).abs() < 1e-12);
    }

    #[test]
    fn spot_power_is_the_cone_integral() {
        let (ci, co) = (0.9f64, 0.5f64);
        let l = light(LightKind::Spot {
            cos_inner: ci,
            cos_outer: co,
        });
        // Midpoint rule over c = cos ψ.
        let n = 200_000;
        let integral: f64 = (0..n)
            .map(|k| {
                let c = co + (1.0 - co) * (k as f64 + 0.5) / n as f64;
                cone_falloff(c, ci, co) * (1.0 - co) / n as f64
            })
            .sum();
        let want = 2.0 * PI * integral * l.intensity;
        assert!((l.power(DVec3::ONE) - want).abs().max_element() < 1e-6 * want.max_element());
    }

    #[test]
    fn a_directional_light_gives_e_cos() {
        let mut l = light(LightKind::Directional);
        l.direction = DVec3::new(1.0, -1.0, 0.0).normalize();
        let got = l.incident(DVec3::ZERO, DVec3::Y, 10.0).unwrap();
        let want = l.intensity * std::f64::consts::FRAC_1_SQRT_2;
        assert!((got.irradiance - want).abs().max_element() < 1e-12);
        assert!((got.toward - DVec3::new(-10.0, 10.0, 0.0) / 2f64.sqrt()).length() < 1e-9);
    }

    #[test]
    fn the_map_is_looked_up_by_direction() {
        // 4×2: the top row bright, the bottom dark; column 2 (φ ∈ [0, π/2),
        // from −z toward +x) red on top.
        let mut texels = vec![[1.0f32; 3]; 4];
        texels.extend(vec![[0.0f32; 3]; 4]);
        texels[2] = [5.0, 0.0, 0.0];
        let map = EnvironmentMap {
            width: 4,
            height: 2,
            texels,
        };
        let up = map.radiance(DVec3::new(0.0, 1.0, 0.0));
        assert!(up.x >= 1.0 && up.y == 1.0, "{up}");
        assert_eq!(map.radiance(DVec3::NEG_Y), DVec3::ZERO);
        // Centre of column 2 on the top row: φ = π/4, θ = π/4.
        let d = DVec3::new(0.5, std::f64::consts::FRAC_1_SQRT_2, -0.5).normalize();
        assert!((map.radiance(d) - DVec3::new(5.0, 0.0, 0.0)).length() < 1e-9);
        assert!((map.mean() - DVec3::splat(0.5) - DVec3::new(0.5, -0.125, -0.125)).length() < 1e-9);
    }
}
