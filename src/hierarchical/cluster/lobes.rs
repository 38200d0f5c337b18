//! Six half-axis lobes (+x, −x, +y, −y, +z, −z): how the cluster levels
//! see directions. A patch of normal n counts in lobe a with weight
//! max(0, ±n_a) / |n|₁ (exact for axis-aligned patches); a cluster's
//! radiance toward a direction is its exposed power over its exposed area
//! in that direction's lobes.
//!
//! Invariant: a normal's lobe weights sum to one, so sharing power by
//! lobes neither creates nor loses any.

use glam::DVec3;

/// Six half-axis lobe weights.
pub type Lobes = [f64; 6];

/// The weights of a unit direction on the six half-axis lobes: the
/// positive and negative parts of its components.
pub fn lobes(d: DVec3) -> Lobes {
    [
        d.x.max(0.0),
        (-d.x).max(0.0),
        d.y.max(0.0),
        (-d.y).max(0.0),
        d.z.max(0.0),
        (-d.z).max(0.0),
    ]
}

/// A normal's lobes scaled to sum to 1: how a patch's power or area is
/// shared among the lobes.
pub fn normal_lobes(n: DVec3) -> Lobes {
    let l = lobes(n);
    let sum: f64 = l.iter().sum();
    if sum > 0.0 { l.map(|w| w / sum) } else { l }
}

pub(super) fn dot(a: &Lobes, b: &Lobes) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

pub(super) fn dot3(a: &[DVec3; 6], b: &Lobes) -> DVec3 {
    a.iter().zip(b).map(|(x, y)| *x * *y).sum()
}

/// What the clusters radiate, per lobe: the exposed power and the
/// exposed area it leaves from.
#[derive(Clone, Debug, Default)]
pub struct Radiance {
    /// Σ B_exposed · A · exposure · normal_lobes(n) over the patches (W).
    pub(super) power: Vec<[DVec3; 6]>,
    /// Σ A · exposure · normal_lobes(n) over the patches (m²).
    pub(super) area: Vec<Lobes>,
}

impl Radiance {
    /// Mean exposed radiosity of cluster `c` seen from direction `out`
    /// (unit, pointing away from it).
    pub(super) fn toward(&self, c: usize, out: DVec3) -> DVec3 {
        let w = lobes(out);
        let a = dot(&self.area[c], &w);
        if a > 0.0 {
            dot3(&self.power[c], &w) / a
        } else {
            DVec3::ZERO
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_lobes_share_one_and_are_exact_on_axes() {
        for n in [DVec3::X, -DVec3::Y, DVec3::new(1.0, 2.0, -2.0).normalize()] {
            let w = normal_lobes(n);
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
        // An axis-aligned normal: the lobe cosine is the true cosine.
        let d = DVec3::new(0.3, -0.5, 0.8).normalize();
        for n in [
            DVec3::X,
            -DVec3::X,
            DVec3::Y,
            -DVec3::Y,
            DVec3::Z,
            -DVec3::Z,
        ] {
            let exact = n.dot(d).max(0.0);
            assert!((dot(&normal_lobes(n), &lobes(d)) - exact).abs() < 1e-12);
        }
    }
}
