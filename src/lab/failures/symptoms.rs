//! The symptoms of a run: what went wrong, named by fixed rules.
//!
//! Owns the tolerances ([`limits`]) and the rules ([`symptoms()`]) that
//! turn a [`Measure`](crate::lab::failures::Measure) into the table's *symptoms* column. Invariant: the
//! rules read only the measurements, the scene's fastest run and the
//! reference's noise, so regenerating the table cannot flatter a method.

use crate::lab::failures::Outcome;

/// Tolerances of [`symptoms()`].
pub mod limits {
    /// Power above the closed form (or absorbed above emitted) by more than
    /// this fraction is energy created.
    pub const ENERGY_CREATED: f64 = 0.02;
    /// Power below the closed form by more than this fraction is light lost.
    pub const LIGHT_LOST: f64 = 0.05;
    /// A render whose mean is off the reference's by more than this is too
    /// bright or too dark.
    pub const IMAGE_BIAS: f64 = 0.10;
    /// A render whose relative RMSE exceeds this (and twice the reference's
    /// noise) without a bias is blotchy: aliasing or noise.
    pub const IMAGE_ERROR: f64 = 0.25;
    /// A run this many times slower than the scene's fastest, and above
    /// [`SLOW_SECONDS`], is slow.
    pub const SLOW_FACTOR: f64 = 20.0;
    /// A run must take more than this many seconds to be slow at all.
    pub const SLOW_SECONDS: f64 = 5.0;
}

/// The symptoms of an outcome, by the rules of [`limits`]; `fastest` is
/// the scene's fastest run in seconds, `noise` the reference's relative
/// noise. Empty when nothing is wrong.
pub fn symptoms(outcome: &Outcome, fastest: f64, noise: f64) -> Vec<String> {
    use limits::*;
    let m = match outcome {
        Outcome::Refused(e) => return vec![format!("refused: {e}")],
        Outcome::Panicked(e) => return vec![format!("PANIC: {e}")],
        Outcome::Ran(m) => m,
    };
    let mut out = Vec::new();
    if m.non_finite {
        out.push("non-finite or negative output (blow-up)".to_string());
    }
    if !m.converged {
        out.push(format!(
            "not converged in {} iterations (slow convergence)",
            m.iterations
        ));
    }
    if let Some(b) = m.budget {
        out.push(format!("refinement stopped at the {} budget", b.noun()));
    }
    match m.power_error {
        Some(e) if e > ENERGY_CREATED => out.push(format!("energy created (+{:.1} %)", 100.0 * e)),
        Some(e) if e < -LIGHT_LOST => out.push(format!("light lost ({:.1} %)", 100.0 * e)),
        None if m.absorbed_ratio > 1.0 + ENERGY_CREATED => out.push(format!(
            "energy created (absorbed {:.3} × emitted)",
            m.absorbed_ratio
        )),
        _ => {}
    }
    if m.image_bias > IMAGE_BIAS {
        out.push(format!("too bright (+{:.0} %)", 100.0 * m.image_bias));
    } else if m.image_bias < -IMAGE_BIAS {
        out.push(format!("too dark ({:.0} %)", 100.0 * m.image_bias));
    } else if m.image_error > IMAGE_ERROR.max(2.0 * noise) {
        out.push(format!(
            "blotchy (image error {:.0} % without bias: aliasing or noise)",
            100.0 * m.image_error
        ));
    }
    if m.seconds > SLOW_SECONDS && m.seconds > SLOW_FACTOR * fastest {
        out.push(format!("slow ({:.0}× the fastest)", m.seconds / fastest));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hierarchical::Budget;
    use crate::lab::failures::Measure;

    fn ran(m: impl FnOnce(&mut Measure)) -> Outcome {
        let mut measure = Measure {
            converged: true,
            iterations: 3,
            seconds: 1.0,
            elements: 10,
            links: 10,
            vertices: 10,
            absorbed_ratio: 0.5,
            power_error: Some(0.0),
            image_error: 0.05,
            image_bias: 0.0,
            non_finite: false,
            budget: None,
        };
        m(&mut measure);
        Outcome::Ran(measure)
    }

    #[test]
    fn symptoms_follow_the_rules() {
        let s = |o: Outcome| symptoms(&o, 1.0, 0.01).join("; ");
        assert_eq!(s(ran(|_| {})), "");
        assert!(s(ran(|m| m.power_error = Some(0.03))).starts_with("energy created"));
        assert!(s(ran(|m| m.power_error = Some(-0.06))).starts_with("light lost"));
        assert_eq!(s(ran(|m| m.power_error = Some(-0.04))), "");
        assert!(
            s(ran(|m| {
                m.power_error = None;
                m.absorbed_ratio = 1.03
            }))
            .starts_with("energy created")
        );
        assert!(s(ran(|m| m.converged = false)).starts_with("not converged in 3"));
        assert!(s(ran(|m| m.image_bias = 0.2)).starts_with("too bright"));
        assert!(s(ran(|m| m.image_bias = -0.2)).starts_with("too dark"));
        assert!(s(ran(|m| m.image_error = 0.3)).starts_with("blotchy"));
        assert!(s(ran(|m| m.seconds = 30.0)).starts_with("slow (30×"));
        assert_eq!(s(ran(|m| m.seconds = 4.0)), "");
        assert!(s(ran(|m| m.non_finite = true)).starts_with("non-finite"));
        assert!(
            s(ran(|m| m.budget = Some(Budget::Elements)))
                .starts_with("refinement stopped at the element budget")
        );
        assert!(s(Outcome::Refused("too big".into())).starts_with("refused: too big"));
        assert!(s(Outcome::Panicked("oops".into())).starts_with("PANIC"));
    }
}
