//! The analysis's verdict: which effect explains the gap, how far it shrinks, whether the
//! baseline stands, and the worst signal left. Must not do I/O.

use super::*;

impl Run<'_> {
    /// The verdict over the sorted candidates `out`.
    pub(super) fn verdict(
        &self,
        out: &[Candidate],
        aliases: &alias::Aliases,
        spread: f64,
    ) -> GapVerdict {
        let base = &self.base;
        if base.fit_quality.residual_verdict == Verdict::Good {
            // Within noise: `none` only when no input instrument can hide behind the health.
            let hidden: Vec<String> = aliases.hidden().into_iter().map(String::from).collect();
            let effect = if hidden.is_empty() { "none" } else { AMBIGUOUS };
            return self.baseline_stands(effect, 0.0, hidden, None);
        }
        let explains = |best: &Candidate| {
            best.shortlisted
                && best.bic_gain > 0.0
                && best.score > spread
                && (best.score >= MIN_SHRINKAGE || best.fit_quality == Verdict::Good)
                && !best.within_model_error()
        };
        match out.first() {
            Some(best) if explains(best) => {
                // A candidate that explains the residual but needs a health less plausible
                // than the baseline's, where an instrument hidden behind the health would make
                // the baseline's plausible, may be a wrong form of that instrument (see
                // `Aliases::against`): the health is in doubt, and both are named.
                let doubted = aliases.against(&best.health);
                if doubted.is_empty() {
                    GapVerdict {
                        effect: best.effect.clone(),
                        confidence: out
                            .get(1)
                            .filter(|second| second.shortlisted)
                            .map_or(best.score, |second| best.score - second.score.max(0.0))
                            .clamp(0.0, 1.0),
                        shrinkage: best.score,
                        health_before: base.health,
                        health_after: best.health,
                        fit_quality_after: best.fit_quality,
                        aliases: Vec::new(),
                        doubted: None,
                    }
                } else {
                    let restoring = doubted.into_iter().map(String::from).collect();
                    self.baseline_stands(
                        AMBIGUOUS,
                        best.score,
                        restoring,
                        Some(best.effect.clone()),
                    )
                }
            }
            _ => {
                // No candidate explains the residual. If the health is better than new and an
                // input instrument that hides behind it would make it plausible, that
                // instrument is as likely a cause as anything the library lacks (a meter
                // drifting through the start-up is no constant factor, yet mostly one): say
                // the health cannot be trusted and name the instruments, not `unexplained`.
                let restoring: Vec<String> =
                    aliases.restoring().into_iter().map(String::from).collect();
                let effect = if restoring.is_empty() {
                    "unexplained"
                } else {
                    AMBIGUOUS
                };
                let shrinkage = out.first().map_or(0.0, |b| b.score.max(0.0));
                self.baseline_stands(effect, shrinkage, restoring, None)
            }
        }
    }

    /// A verdict that adopts no effect: the health after, and its fit quality, are the
    /// baseline's (`none`, `unexplained`, `ambiguous`).
    pub(super) fn baseline_stands(
        &self,
        effect: &str,
        shrinkage: f64,
        aliases: Vec<String>,
        doubted: Option<String>,
    ) -> GapVerdict {
        GapVerdict {
            effect: effect.into(),
            confidence: 0.0,
            shrinkage,
            health_before: self.base.health,
            health_after: self.base.health,
            fit_quality_after: self.base.fit_quality.verdict,
            aliases,
            doubted,
        }
    }

    /// The worst signal of the baseline's residual map: measured, the baseline model, and the
    /// verdict's model (when it names one fitted on the whole start-up).
    pub(super) fn worst_signal(
        &self,
        verdict: &GapVerdict,
        models: &BTreeMap<String, Vec<Values>>,
    ) -> Option<SignalTraces> {
        let base = &self.base;
        base.localisation
            .iter()
            .filter(|c| c.norm_error.is_finite())
            .max_by(|a, b| a.norm_error.total_cmp(&b.norm_error))
            .filter(|_| !base.model_values.is_empty())
            .map(|c| {
                let i = c.signal.index();
                let column = |rows: &[Values]| rows.iter().map(|v| v[i]).collect::<Vec<f64>>();
                SignalTraces {
                    signal: c.signal,
                    t_s: self.rec.times().to_vec(),
                    measured: column(self.rec.rows()),
                    before: column(&base.model_values),
                    after: models
                        .get(&verdict.effect)
                        .filter(|m| !m.is_empty())
                        .map(|m| (verdict.effect.clone(), column(m))),
                }
            })
    }
}
