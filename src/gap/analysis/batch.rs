//! The analysis's first batch (seed refits of the baseline, its folds or held-out start-up,
//! every candidate's screen fit) and the screen's ranking of the candidates. Must not do I/O.

use super::*;

impl Run<'_> {
    /// First batch, all independent of each other: what optimiser and noise variation alone do
    /// to the residual (the baseline refitted with other seeds; a candidate's shrinkage must
    /// exceed it); the baseline on the held-out start-up or on each fold; and the screen: every
    /// candidate fitted on the whole start-up at a reduced budget from the baseline's health
    /// (its start nest is the baseline itself, so a candidate never screens worse than the
    /// baseline), ranked by how far it shrinks the residual there. The full-budget fits go
    /// first so that the pool's workers finish together.
    pub(super) fn first_batch(&self, names: &[Trial]) -> Result<FirstBatch, DiagnosisError> {
        let mut jobs: Vec<BaseJob> = (1..=SEED_REFITS).map(BaseJob::Seed).collect();
        match self.scoring {
            Scoring::Holdout => jobs.push(BaseJob::Holdout),
            Scoring::BlockedCv => jobs.extend([BaseJob::Fold(0), BaseJob::Fold(1)]),
        }
        let mut by_size: Vec<usize> = (0..names.len()).collect();
        by_size.sort_by_key(|&i| std::cmp::Reverse(names[i].params.len()));
        jobs.extend(by_size.into_iter().map(BaseJob::Screen));
        let done = in_parallel(self.threads, &jobs, |job| self.base_job(*job, names))?;
        let mut ssrs = vec![self.base.ssr];
        let mut base_test = 0.0;
        let mut base_folds: Vec<MethodResult> = Vec::new();
        let mut screens: Vec<Option<MethodResult>> = vec![None; names.len()];
        for (job, r) in jobs.iter().zip(done) {
            match (job, r) {
                (BaseJob::Screen(i), BaseOut::Screen(f)) => screens[*i] = f,
                (BaseJob::Seed(_), BaseOut::Fit(Ok(f))) => ssrs.push(f.fit.ssr),
                (BaseJob::Seed(_), _) => {}
                (_, BaseOut::Fit(Ok(f))) => {
                    base_test += f.test_ssr;
                    base_folds.push(f.fit);
                }
                // The baseline must be scorable: its error is the analysis's error.
                (_, BaseOut::Fit(Err(e))) => return Err(e),
                (_, BaseOut::Screen(_)) => {}
            }
        }
        let lo = ssrs.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = ssrs.iter().copied().fold(0.0, f64::max);
        Ok(FirstBatch {
            jobs: jobs.len(),
            optimiser_spread: ((hi - lo) / lo.max(1e-300)).clamp(0.0, 1.0),
            base_test,
            base_folds,
            screens,
        })
    }

    /// Runs one job of the first batch.
    pub(super) fn base_job(&self, job: BaseJob, names: &[Trial]) -> BaseOut {
        let (engine, rec, single) = (self.engine, self.rec, &self.single);
        match job {
            BaseJob::Seed(k) => {
                let seeded = DiagnosisConfig {
                    seed: self.cfg.seed.wrapping_add(k),
                    ..single.clone()
                };
                BaseOut::Fit(diagnose_transient(engine, rec, &seeded).map(|fit| FoldFit {
                    fit,
                    test_ssr: f64::NAN,
                }))
            }
            BaseJob::Holdout => BaseOut::Fit(
                self.holdout
                    .ok_or_else(|| DiagnosisError::Config("no holdout".into()))
                    .and_then(|h| diagnose_transient(engine, h, single))
                    .map(|fit| FoldFit {
                        test_ssr: fit.ssr,
                        fit,
                    }),
            ),
            BaseJob::Fold(p) => BaseOut::Fit(fit_fold(engine, rec, single, p)),
            BaseJob::Screen(i) => BaseOut::Screen(
                diagnose_transient(engine, rec, &self.screen_cfg(&names[i].params)).ok(),
            ),
        }
    }

    /// Ranks the screened candidates by their screen shrinkage: the shortlist (indices into
    /// `names`) to score on held-out data, and the rest as candidates keeping their screen's
    /// fit.
    pub(super) fn rank_screen(
        &self,
        names: &[Trial],
        screens: &[Option<MethodResult>],
    ) -> (Vec<usize>, Vec<Candidate>) {
        let screen_shrinkage = |i: usize| self.shrinkage(screens[i].as_ref());
        // Candidates whose model failed on the data are no explanation of it.
        let mut ranked: Vec<usize> = (0..names.len()).filter(|&i| screens[i].is_some()).collect();
        ranked.sort_by(|&a, &b| {
            let (sa, sb) = (screen_shrinkage(a), screen_shrinkage(b));
            sb.unwrap_or(0.0).total_cmp(&sa.unwrap_or(0.0))
        });
        let lead = ranked
            .first()
            .and_then(|&i| screen_shrinkage(i))
            .unwrap_or(0.0);
        let shortlist: Vec<usize> = ranked
            .iter()
            .copied()
            .enumerate()
            .take_while(|&(rank, i)| {
                rank == 0
                    || (rank < SHORTLIST
                        && screen_shrinkage(i).unwrap_or(0.0) >= SHORTLIST_RATIO * lead)
            })
            .map(|(_, i)| i)
            .collect();
        let mut rest = Vec::new();
        for &i in ranked.iter().skip(shortlist.len()) {
            let Some(fit) = &screens[i] else { continue };
            let train = 1.0 - fit.ssr / self.base.ssr.max(1e-300);
            rest.push(Candidate {
                effect: names[i].effect.clone(),
                params: effect_params(fit),
                screen_shrinkage: train,
                shortlisted: false,
                predicted_shrinkage: names[i].predicted,
                train_shrinkage: train,
                heldout_shrinkage: None,
                bic_gain: bic(&self.base, self.k_base)
                    - bic(fit, self.k_base + names[i].params.len()),
                score: train,
                health: fit.health,
                fit_quality: fit.fit_quality.verdict,
                normalised_residual: fit.fit_quality.normalised_residual,
                model_error: None,
            });
        }
        (shortlist, rest)
    }
}
