//! The leader's refit, and its refinement where its effect has one (kept on a BIC gain).
//! Must not do I/O.

use super::*;

impl Run<'_> {
    /// Cross-validated: the leader is refitted on the whole start-up, so its health, parameters
    /// and fit quality are those of the complete data (the others keep their fold means).
    pub(super) fn refit_leader(&self, fitted: &mut Fitted) -> Result<(), DiagnosisError> {
        let Some(best) = fitted.candidates.first_mut().filter(|b| b.shortlisted) else {
            return Ok(());
        };
        // From the screen's solution: the full fit can only improve on it.
        let (e, start) = match fitted.screened.get(&best.effect) {
            Some(screen) => (with_effect_params(self.engine, screen)?, screen.health),
            None => (self.engine.clone(), self.base.health),
        };
        let c_cfg = DiagnosisConfig {
            extra_params: fit_params(&best.effect, self.rec),
            max_model_runs: candidate_runs(self.cfg, best.params.len()),
            base: start,
            ..self.cfg.clone()
        };
        fitted.fits += 1;
        if let Ok(fit) = diagnose_transient(&e, self.rec, &c_cfg) {
            let (fit, refits) = self.refine(&best.effect, &e, fit);
            fitted.fits += refits;
            take_fit(best, &fit, &mut fitted.models);
        }
        fitted.stages.leader = fitted.lap.elapsed().as_secs_f64();
        Ok(())
    }

    /// Held-out scoring: the leader, already fitted on the whole start-up, gets its effect's
    /// refinement as under cross-validation (its score stays the simple form's, so the
    /// refinement cannot change the verdict; it only sharpens the health).
    pub(super) fn refine_holdout_leader(&self, fitted: &mut Fitted) {
        let Some(best) = fitted.candidates.first_mut().filter(|b| b.shortlisted) else {
            return;
        };
        let Some(fit) = fitted.whole.remove(&best.effect) else {
            return;
        };
        let lap = Instant::now();
        let (fit, refits) = self.refine(&best.effect, self.engine, fit);
        if refits > 0 {
            fitted.fits += refits;
            take_fit(best, &fit, &mut fitted.models);
            fitted.stages.leader = lap.elapsed().as_secs_f64();
        }
    }

    /// The named effect's refinement, when it has one (`tip_clearance`'s second casing node,
    /// `vigv_schedule`'s efficiency change and fade width):
    /// fitted from `fit`'s solution with every parameter free, and kept when the start-up
    /// supports its extra parameters (BIC lower by [`REFINEMENT_BIC_GAIN`]). The screen and
    /// the scoring compare every candidate in its simple form, so a refinement cannot win a
    /// verdict for its effect; it only sharpens the health once that effect is named — where
    /// a plant's form differs from the library's (a casing of two time constants against one),
    /// what the simple form leaves is otherwise read as health. Returns the fit to keep and the
    /// refits run.
    pub(super) fn refine(
        &self,
        effect: &str,
        engine: &Engine,
        fit: MethodResult,
    ) -> (MethodResult, usize) {
        let refined = refined_params(effect, self.rec);
        if refined.is_empty() {
            return (fit, 0);
        }
        let Ok(e) = with_effect_params(engine, &fit) else {
            return (fit, 0);
        };
        let k_simple = self.k_base + fit_params(effect, self.rec).len();
        let k_refined = self.k_base + refined.len();
        let r_cfg = DiagnosisConfig {
            max_model_runs: candidate_runs(self.cfg, refined.len()),
            base: fit.health,
            extra_params: refined,
            ..self.cfg.clone()
        };
        // At its default a refinement does nothing and its parameters have no gradient, so each
        // start sets them where they act (the effect says where); the fits run in parallel,
        // the lowest is kept.
        let starts: Vec<Engine> = refinement_starts(effect, &fit)
            .into_iter()
            .filter_map(|set| {
                let mut s = e.clone();
                set.iter()
                    .try_for_each(|(k, v)| s.set_param(k, *v))
                    .ok()
                    .map(|()| s)
            })
            .collect();
        let runs = starts.len();
        // A refined fit with a parameter on its bound is not identified: a casing node that
        // never warms within the record (its time constant at the limit) acts as a constant
        // efficiency change, which the health's D_ET already is, and the two trade along a
        // valley the fit ends anywhere in (measured: D_ET 0.66 points off with a fit `good`).
        let bounds = r_cfg.extra_params.clone();
        let best = in_parallel(self.threads, &starts, |s| {
            diagnose_transient(
                s,
                self.rec,
                &DiagnosisConfig {
                    threads: Some(1),
                    ..r_cfg.clone()
                },
            )
            .ok()
        })
        .ok()
        .into_iter()
        .flatten()
        .flatten()
        .filter(|r| !on_a_bound(r, &bounds))
        .min_by(|a, b| a.ssr.total_cmp(&b.ssr));
        match best {
            Some(r) if bic(&fit, k_simple) - bic(&r, k_refined) > REFINEMENT_BIC_GAIN => (r, runs),
            _ => (fit, runs),
        }
    }
}
