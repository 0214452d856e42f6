//! Which inlet pressure-loss law the baseline shows: a loss ∝ (corrected flow)² (a fixed loss
//! coefficient times dynamic head, gtwatch's default) or a constant fraction of ambient
//! pressure (GSP/GSPy's inlet, and a peer simulator's) — decided from the measured inlet
//! pressure P1 against the ambient pressure, the one duct whose loss a plant measures directly.
//!
//! Why: the law is a word in the engine file, and no number the calibration fits can turn one
//! law into the other. On a unit whose inlet holds its pressure ratio, md22's flow-squared law
//! left P1 residuals running from +1.3 σ at 40 % load to −1.0 σ at full load, and the
//! adaptation bent the maps to absorb what it could (GSPy's generator unit in
//! `tests/gspy_adaptation.rs`: data RMS 1.48 σ with the file's law, 1.02 σ with the constant
//! one, and 19 of 20 degradation levels diagnosed `good` against 15).
//!
//! How: per point the measured loss fraction f = 1 − P1/P_amb, with σ from P1's and the
//! ambient pressure's noise; each law is a one-number model of f — a constant k, or k·r² with
//! r² the flow-squared model's own (corrected flow / design)² at that point, read from the
//! healthy engine's P1 — fitted by weighted least squares. The file's law is kept unless the
//! other one's χ² is lower by [`DECISIVE_CHI2`].
//!
//! What it must not do: I/O; decide on data that cannot tell (fewer than [`MIN_POINTS`]
//! points with P1 and a measured ambient pressure, or an ambient pressure that was itself
//! derived from P1 through the law).

use super::problem::CalibrationPoint;
use crate::engine::config::PressureLossLaw;
use crate::engine::Engine;
use crate::signals::Signal;
use serde::Serialize;

/// How much lower (χ², i.e. squared noise σ summed over the points) the other law's misfit of
/// the measured inlet loss must be before the file's law is replaced: 9 is a three-σ
/// preference on one added degree of freedom's scale, so noise alone does not flip the law.
pub const DECISIVE_CHI2: f64 = 9.0;

/// Fewest points with P1 and a measured ambient pressure that can tell the laws apart.
pub const MIN_POINTS: usize = 3;

/// What the baseline says of the inlet loss law.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InletLawChoice {
    /// The law the engine file had.
    pub file_law: PressureLossLaw,
    /// The law the calibration uses (and writes): the file's unless the other is decisively
    /// better.
    pub chosen: PressureLossLaw,
    /// The chosen law's design loss fraction from this fit: where the law changed, the
    /// engine's value and the design calibration's first guess (refitted where identified).
    pub frac: f64,
    /// χ² of each law's best fit to the measured loss fractions, and the points they use.
    pub chi2_flow_squared: f64,
    pub chi2_constant: f64,
    pub points: usize,
}

impl InletLawChoice {
    /// Whether the calibration changed the file's law.
    pub fn changed(&self) -> bool {
        self.chosen != self.file_law
    }

    /// One line for the report.
    pub fn summary(&self) -> String {
        let fits = format!(
            "the measured inlet loss (1 − P1/P_amb at {} points) fits a loss ∝ (corrected \
             flow)² with χ² {:.2} and a constant fraction with χ² {:.2}",
            self.points, self.chi2_flow_squared, self.chi2_constant
        );
        if self.changed() {
            format!(
                "design.inlet_loss_law: {} (the file said {}): {fits}",
                self.chosen.name(),
                self.file_law.name()
            )
        } else {
            format!(
                "design.inlet_loss_law: {} kept: {fits} (the other law would need a χ² lower \
                 by {DECISIVE_CHI2})",
                self.chosen.name()
            )
        }
    }
}

/// One point's measured loss fraction, its σ, and the flow-squared model's r² there.
#[derive(Debug, Clone, Copy, PartialEq)]
struct LossPoint {
    f: f64,
    sd: f64,
    r2: f64,
}

/// The law the data in `points` show for `engine`'s inlet, or `None` when they cannot tell
/// (see the module docs).
pub fn choose(
    engine: &Engine,
    points: &[CalibrationPoint],
    ambient_from_p1: bool,
) -> Option<InletLawChoice> {
    let file_law = engine.cfg().design.inlet_loss_law;
    if ambient_from_p1
        || !matches!(
            file_law,
            PressureLossLaw::FlowSquared | PressureLossLaw::Constant
        )
    {
        return None;
    }
    // The flow-squared model's r² at each point, from its own P1: r² = (1 − P1/P_amb)/k.
    let mut cfg = engine.cfg().clone();
    let k = cfg.design.inlet_loss_frac.max(0.005);
    cfg.design.inlet_loss_law = PressureLossLaw::FlowSquared;
    cfg.design.inlet_loss_frac = k;
    let flow_squared = engine.with_config(cfg).ok()?;
    let loss: Vec<LossPoint> = points
        .iter()
        .filter_map(|p| {
            let &(_, p1, sd_p1) = p.data.outputs.iter().find(|o| o.0 == Signal::P1)?;
            let p_amb = p.data.inputs.p_amb_kpa;
            let m = flow_squared.model_at(&p.health, p.data.inputs.t_amb_k, p_amb);
            let s = p.data.solve_on(&m).ok()?;
            let r2 = (1.0 - s.stations.p1_kpa / p_amb) / k;
            let f = 1.0 - p1 / p_amb;
            // f = 1 − P1/P_amb: ∂f/∂P1 = −1/P_amb, ∂f/∂P_amb = P1/P_amb².
            let sd_amb = p.data.input_sd.p_amb_kpa;
            let sd = (sd_p1 / p_amb).hypot(sd_amb * p1 / (p_amb * p_amb));
            (f.is_finite() && r2.is_finite() && r2 > 0.0 && sd > 0.0).then_some(LossPoint {
                f,
                sd,
                r2,
            })
        })
        .collect();
    decide(file_law, &loss)
}

/// The weighted least-squares fits of both laws to `loss` and the decision.
fn decide(file_law: PressureLossLaw, loss: &[LossPoint]) -> Option<InletLawChoice> {
    if loss.len() < MIN_POINTS {
        return None;
    }
    // f ≈ k·g with g = 1 (constant) or r² (flow squared): k = Σ f g/σ² / Σ g²/σ².
    let fit = |g: &dyn Fn(&LossPoint) -> f64| -> (f64, f64) {
        let num: f64 = loss.iter().map(|p| p.f * g(p) / (p.sd * p.sd)).sum();
        let den: f64 = loss.iter().map(|p| g(p) * g(p) / (p.sd * p.sd)).sum();
        let k = num / den;
        let chi2 = loss.iter().map(|p| ((p.f - k * g(p)) / p.sd).powi(2)).sum();
        (k, chi2)
    };
    let (k_c, chi2_c) = fit(&|_| 1.0);
    let (k_2, chi2_2) = fit(&|p| p.r2);
    if !(k_c.is_finite() && k_2.is_finite() && chi2_c.is_finite() && chi2_2.is_finite()) {
        return None;
    }
    let chosen = match file_law {
        PressureLossLaw::FlowSquared if chi2_c + DECISIVE_CHI2 <= chi2_2 && k_c >= 0.0 => {
            PressureLossLaw::Constant
        }
        PressureLossLaw::Constant if chi2_2 + DECISIVE_CHI2 <= chi2_c && k_2 >= 0.0 => {
            PressureLossLaw::FlowSquared
        }
        other => other,
    };
    Some(InletLawChoice {
        file_law,
        chosen,
        frac: if chosen == PressureLossLaw::Constant {
            k_c
        } else {
            k_2
        },
        chi2_flow_squared: chi2_2,
        chi2_constant: chi2_c,
        points: loss.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Loss fractions at r² from 0.3 to 1, σ 0.0002 (0.02 kPa of 100), by `law` with 1 % at
    /// design, with a small alternating error.
    fn points(law: PressureLossLaw) -> Vec<LossPoint> {
        (0..9)
            .map(|i| {
                let r2 = 0.3 + 0.7 * i as f64 / 8.0;
                let noise = if i % 2 == 0 { 0.0001 } else { -0.0001 };
                let f = match law {
                    PressureLossLaw::Constant => 0.01,
                    _ => 0.01 * r2,
                } + noise;
                LossPoint { f, sd: 0.0002, r2 }
            })
            .collect()
    }

    #[test]
    fn a_constant_inlet_loss_replaces_the_files_flow_squared_law() {
        let c = decide(
            PressureLossLaw::FlowSquared,
            &points(PressureLossLaw::Constant),
        )
        .expect("decided");
        assert_eq!(c.chosen, PressureLossLaw::Constant);
        assert!(c.changed());
        assert!((c.frac - 0.01).abs() < 1e-4, "{}", c.frac);
        assert!(c.chi2_constant + DECISIVE_CHI2 <= c.chi2_flow_squared);
        assert!(
            c.summary().contains("the file said flow_squared"),
            "{}",
            c.summary()
        );
    }

    #[test]
    fn a_flow_squared_loss_replaces_the_files_constant_law() {
        let c = decide(
            PressureLossLaw::Constant,
            &points(PressureLossLaw::FlowSquared),
        )
        .expect("decided");
        assert_eq!(c.chosen, PressureLossLaw::FlowSquared);
        assert!((c.frac - 0.01).abs() < 1e-4, "{}", c.frac);
    }

    #[test]
    fn data_that_cannot_tell_keep_the_files_law() {
        // Noise far above the difference the laws make.
        let vague: Vec<LossPoint> = points(PressureLossLaw::Constant)
            .into_iter()
            .map(|p| LossPoint { sd: 0.01, ..p })
            .collect();
        for law in [PressureLossLaw::FlowSquared, PressureLossLaw::Constant] {
            let c = decide(law, &vague).expect("decided");
            assert_eq!(c.chosen, law);
            assert!(!c.changed());
            assert!(c.summary().contains("kept"), "{}", c.summary());
        }
        // Too few points.
        assert!(decide(
            PressureLossLaw::FlowSquared,
            &points(PressureLossLaw::Constant)[..MIN_POINTS - 1]
        )
        .is_none());
    }
}
