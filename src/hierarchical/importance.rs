//! View importance \[SAS92\]: per patch, how much its light matters to what
//! a view sees, carried back along the links, as the weight of each
//! receiver's link errors.
//!
//! Invariant: weights are in [0, 1]; without importance every patch
//! counts fully.

use crate::hierarchical::solver::Solver;

/// Jacobi sweeps of the importance equation per update.
const IMPORTANCE_SWEEPS: usize = 12;

impl Solver<'_> {
    /// Carries the view's importance back along the links: Y = R + Kᵀ Y
    /// per patch, R the directly seen patches and K_pq the share of p's
    /// radiosity that its element links gather from q (Σ over links of
    /// A_r / A_p · ρ_p · F·V), by Jacobi sweeps; the weights are Y capped
    /// at 1. (Cluster links are left out: they carry far, weak light.)
    pub(super) fn update_importance(&mut self) {
        let Some(seen) = &self.settings.importance else {
            return;
        };
        let (scene, h) = (self.scene, &self.hierarchy);
        let terms: Vec<(u32, u32, f64)> = self
            .links
            .iter()
            .enumerate()
            .flat_map(|(r, ls)| {
                let re = &h.elements[r];
                let p = &scene.patches[re.patch as usize];
                let share = re.area / p.area * p.reflectance.max_element();
                ls.iter()
                    .map(move |l| (re.patch, h.get(l.source).patch, share * l.coupling()))
            })
            .collect();
        let seen: Vec<f64> = seen.iter().map(|&v| f64::from(v)).collect();
        let mut y = seen.clone();
        for _ in 0..IMPORTANCE_SWEEPS {
            let mut next = seen.clone();
            for &(p, q, k) in &terms {
                next[q as usize] += k * y[p as usize];
            }
            y = next;
        }
        self.weight = y.into_iter().map(|v| v.min(1.0)).collect();
        if let Some(c) = &mut self.clusters {
            c.set_weights(&self.weight);
        }
    }
}
