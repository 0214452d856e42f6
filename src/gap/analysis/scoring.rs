//! The shortlist's scoring: each candidate fitted on the whole recording and judged on data it
//! was not fitted to (the held-out start-up, or the cross-validation folds). Must not do I/O.

use super::*;

impl Run<'_> {
    /// The shortlist's scoring jobs: one per candidate (holdout), or one per candidate and fold
    /// (cross-validation, when the baseline fitted both folds).
    pub(super) fn scoring_jobs(&self, shortlist: &[usize], base_folds: usize) -> Vec<ScoreJob> {
        match self.scoring {
            Scoring::Holdout => shortlist.iter().map(|&i| (i, None)).collect(),
            Scoring::BlockedCv if base_folds == 2 => shortlist
                .iter()
                .flat_map(|&i| [(i, Some(0)), (i, Some(1))])
                .collect(),
            Scoring::BlockedCv => Vec::new(),
        }
    }

    /// Third batch: the shortlist scored on data its fits did not see. Holdout: a full fit on
    /// the whole start-up from the screen's solution, then the held-out start-up with its
    /// effect parameters kept and the health refitted. Cross-validation: each fold fitted from
    /// the baseline's fit of the same fold (which saw only that fold).
    pub(super) fn score_shortlist(
        &self,
        names: &[Trial],
        first: &FirstBatch,
        jobs: &[ScoreJob],
    ) -> Result<Vec<Result<CandidateFit, DiagnosisError>>, DiagnosisError> {
        in_parallel(
            self.threads,
            jobs,
            |&(i, fold)| -> Result<CandidateFit, DiagnosisError> {
                let extra = &names[i].params;
                match fold {
                    Some(p) => {
                        let c_cfg = self.cand_cfg(extra, first.base_folds[usize::from(p)].health);
                        fit_fold(self.engine, self.rec, &c_cfg, p).map(CandidateFit::Fold)
                    }
                    None => self.fit_whole(extra, first.screens[i].as_ref()),
                }
            },
        )
    }

    /// A candidate fitted on the whole start-up from its screen's solution, and the held-out
    /// start-up's SSR with its effect parameters kept and the health refitted.
    pub(super) fn fit_whole(
        &self,
        extra: &[FitParam],
        screened: Option<&MethodResult>,
    ) -> Result<CandidateFit, DiagnosisError> {
        let screened = screened.ok_or_else(|| DiagnosisError::Config("not screened".into()))?;
        let e = with_effect_params(self.engine, screened)?;
        let fit = diagnose_transient(&e, self.rec, &self.cand_cfg(extra, screened.health))?;
        let heldout_ssr = match self.holdout {
            Some(h) => {
                let e = with_effect_params(self.engine, &fit)?;
                diagnose_transient(&e, h, &self.single).ok().map(|r| r.ssr)
            }
            None => None,
        };
        Ok(CandidateFit::Whole { fit, heldout_ssr })
    }

    /// A shortlisted candidate scored on the held-out start-up.
    pub(super) fn holdout_candidate(
        &self,
        trial: &Trial,
        screen: f64,
        fit: &MethodResult,
        heldout_ssr: Option<f64>,
        base_test: f64,
    ) -> Candidate {
        let train = 1.0 - fit.ssr / self.base.ssr.max(1e-300);
        let heldout = heldout_ssr.map(|s| 1.0 - s / base_test.max(1e-300));
        Candidate {
            effect: trial.effect.clone(),
            params: effect_params(fit),
            screen_shrinkage: screen,
            shortlisted: true,
            predicted_shrinkage: trial.predicted,
            train_shrinkage: train,
            heldout_shrinkage: heldout,
            bic_gain: bic(&self.base, self.k_base) - bic(fit, self.k_base + trial.params.len()),
            score: heldout.unwrap_or(train),
            health: fit.health,
            fit_quality: fit.fit_quality.verdict,
            normalised_residual: fit.fit_quality.normalised_residual,
            model_error: None,
        }
    }

    /// A shortlisted candidate scored by two-fold cross-validation: the fold means.
    pub(super) fn cv_candidate(
        &self,
        trial: &Trial,
        screen: f64,
        [a, b]: [&FoldFit; 2],
        first: &FirstBatch,
    ) -> Candidate {
        let (k_base, k) = (self.k_base, self.k_base + trial.params.len());
        let base_folds = &first.base_folds;
        let train_ssr = a.fit.ssr + b.fit.ssr;
        let base_train = base_folds[0].ssr + base_folds[1].ssr;
        let heldout = 1.0 - (a.test_ssr + b.test_ssr) / first.base_test.max(1e-300);
        let (pa, pb) = (effect_params(&a.fit), effect_params(&b.fit));
        let params = pa
            .iter()
            .map(|(key, (va, sa))| {
                let (vb, sb) = pb.get(key).copied().unwrap_or((*va, *sa));
                (key.clone(), (0.5 * (va + vb), 0.5 * (sa + sb)))
            })
            .collect();
        Candidate {
            effect: trial.effect.clone(),
            params,
            screen_shrinkage: screen,
            shortlisted: true,
            predicted_shrinkage: trial.predicted,
            train_shrinkage: 1.0 - train_ssr / base_train.max(1e-300),
            heldout_shrinkage: Some(heldout),
            bic_gain: bic(&base_folds[0], k_base) + bic(&base_folds[1], k_base)
                - bic(&a.fit, k)
                - bic(&b.fit, k),
            score: heldout,
            health: mean_health(&a.fit.health, &b.fit.health),
            fit_quality: worse(a.fit.fit_quality.verdict, b.fit.fit_quality.verdict),
            normalised_residual: 0.5
                * (a.fit.fit_quality.normalised_residual + b.fit.fit_quality.normalised_residual),
            model_error: None,
        }
    }
}
