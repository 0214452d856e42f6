//! The growth's end: the final shape's report, the model's own error (per signal and along
//! the GG speed) and its error in health units written into the engine's `[adaptation]`.
//! Must not do I/O.

use super::*;

impl<'a> Growth<'a> {
    /// The report and the adapted engine. σ of the final knots: from the last
    /// identifiability pass at the final count, else a pass now.
    pub(in super::super) fn finish(
        mut self,
        rms_before: f64,
    ) -> Result<(AdaptReport, Engine), CalibrateError> {
        let final_keys: Vec<String> = self
            .design_free
            .iter()
            .cloned()
            .chain(self.shape.keys())
            .collect();
        let sigma: Vec<(String, Option<f64>)> = if final_keys
            .iter()
            .all(|k| self.last_sigma.iter().any(|(x, _)| x == k))
        {
            std::mem::take(&mut self.last_sigma)
        } else {
            let cands = candidates_for(&self.current, &final_keys)?;
            let pass = identify_at(&self.current, &cands, self.ctx)?;
            self.runs += pass.runs;
            final_keys.iter().cloned().zip(pass.sigma).collect()
        };
        let bounds: Vec<(String, f64, f64)> = candidates_for(&self.current, &self.shape.keys())?
            .into_iter()
            .map(|c| {
                let r = crate::engine::config::param_range(&c.key)
                    .map_or((f64::NEG_INFINITY, f64::INFINITY), |r| (r.min, r.max));
                (c.key, r.0, r.1)
            })
            .collect();
        let (mut error, runs) =
            model_error::estimate(&self.current, &final_keys, &self.shape, self.ctx)?;
        self.runs += runs;
        let shape_keys = self.shape.keys();
        if error.folds < model_error::MIN_FOLDS && final_keys.len() > shape_keys.len() {
            // With every design value free beside many knots, leaving one point out can leave
            // part of the fit pinned by that point alone, and every fold is skipped: the
            // diagnosis would then weigh the adapted model as exact. Held at their fitted
            // values, the design values still carry the shape's own uncertainty (on the first
            // foreign unit, a design pressure ratio written 20.93 grew the compressor to six
            // knots and skipped all 7 folds with the 8 design values free).
            let (held, runs) =
                model_error::estimate(&self.current, &shape_keys, &self.shape, self.ctx)?;
            self.runs += runs;
            if held.folds >= model_error::MIN_FOLDS {
                let note = format!(
                    "{}; the design values held at their fitted values (with them free: {})",
                    held.note, error.note
                );
                error = ModelError { note, ..held };
            }
        }
        // Advice only: a point the fit solved that fails to solve here costs the advice, not
        // the calibration.
        let coverage = error
            .by_speed
            .as_ref()
            .and_then(|by| {
                let gg = super::super::gg_speeds(&self.current, self.ctx.points).ok()?;
                let lines: Vec<u64> = self.ctx.points.iter().map(|p| p.line).collect();
                Some(super::super::coverage::advice(&gg, &lines, by))
            })
            .unwrap_or_default();
        let reach = CalibratedRange {
            gg_speed: self.ranges[0],
        };
        let current = with_model_error_and_reach(&self.current, &error, reach)?;
        let health = if self.ctx.settings.health_error {
            let (health, runs) =
                health_error::estimate(&current, &final_keys, &self.shape, self.ctx)?;
            self.runs += runs;
            health
        } else {
            HealthError {
                note: "not estimated (a calibration to predict a point left out)".into(),
                ..HealthError::default()
            }
        };
        let current = with_health_error(&current, &health)?;
        let mut r = report(
            &self.shape,
            &self.ranges,
            self.not_fitted,
            self.knots_reason,
            &sigma,
            &bounds,
        );
        r.rms_before = rms_before;
        r.rms_after = rms_of(&self.current, self.ctx)?;
        r.design_refitted = self.design_free;
        r.model_runs = self.runs;
        r.strategy = self.ctx.settings.strategy.name();
        r.steps = self.steps;
        r.model_error = error;
        r.health_error = health;
        r.coverage = coverage;
        r.calibrated = Some(reach);
        r.fitted = Some((final_keys, self.shape));
        Ok((r, current))
    }
}

/// `engine` with `error` as its file's `[adaptation.model_error_pct]` and
/// `[adaptation.model_error_by_speed]`, and `reach` (the data's lowest and highest relative
/// corrected GG speed) as `[adaptation.calibrated]` (replacing any older ones); an older
/// `[adaptation.health_error]` is cleared (estimated again on this engine by
/// [`health_error::estimate`], which must not read with it).
fn with_model_error_and_reach(
    engine: &Engine,
    error: &ModelError,
    reach: CalibratedRange,
) -> Result<Engine, CalibrateError> {
    let mut cfg = engine.cfg().clone();
    if let Some(a) = cfg.adaptation.as_mut() {
        a.model_error_pct = error
            .signals
            .iter()
            .map(|s| (s.signal.clone(), s.pct))
            .collect();
        a.model_error_by_speed = error.by_speed.clone();
        a.calibrated = Some(reach);
        a.health_error.clear();
    }
    engine
        .with_config(cfg)
        .map_err(|e| CalibrateError::Model(e.to_string()))
}

/// `engine` with `health` as its file's `[adaptation.health_error]` (when estimated).
pub(in super::super) fn with_health_error(
    engine: &Engine,
    health: &HealthError,
) -> Result<Engine, CalibrateError> {
    if health.points.is_empty() {
        return Ok(engine.clone());
    }
    let mut cfg = engine.cfg().clone();
    if let Some(a) = cfg.adaptation.as_mut() {
        a.health_error = health.points.clone();
    }
    engine
        .with_config(cfg)
        .map_err(|e| CalibrateError::Model(e.to_string()))
}
