//! The second look a component stopped by the identifiability analysis gets once nothing grows
//! and the fit is not within noise: its knot(s) more fitted, then judged at the fitted values
//! rather than at the re-sampled start. Must not do I/O.

use super::*;

/// What a second look found ([`Growth::look`]).
enum Look {
    /// The fit did not gain.
    NoGain,
    /// It gained, but these curves of the components that grew are not identified at the
    /// fitted values.
    Unidentified(Vec<(usize, String)>),
    /// Kept: the fitted engine, its keys and the identifiability pass at the fitted values.
    Kept(Box<(Engine, Vec<String>, Pass)>),
}

impl<'a> Growth<'a> {
    /// When nothing grows any more and the fit is not within noise: the components the
    /// identifiability analysis stopped at a growth's start, given one knot more, and those
    /// whose next knot was fitted and no better, two more; fitted, judged by the same analysis
    /// at the fitted values (all together, then each alone), and kept where every knot is
    /// identified there and the data's RMS falls by [`MIN_GAIN`]; a component alone whose
    /// knots are identified on some curves only is tried again with the others held at their
    /// fit. `true` when one grew (it grows on as any other).
    ///
    /// Why two knots: one more knot can gain nothing where two gain much (on GSPy's generator
    /// unit with its design GG speed written 9 831 rpm, the compressor's third knot took the
    /// data's RMS from 1.54 to 1.52 σ, its fourth to 0.94 σ, with its flow held).
    ///
    /// Why: the analysis at a growth's start looks at the re-sampled curves of a fit that
    /// misses the data by many σ, where the Jacobian is not the one at the optimum; whether it
    /// identifies a knot there can flip with the design values' last digits. On the first
    /// foreign unit of `tests/foreign_engine.rs` (combinator load) a design pressure ratio
    /// written 20.9291 instead of 20.929142 stopped the compressor and the HP turbine at one
    /// knot (data RMS 5.16 σ, `poor`) where the exact value grew them to five (0.62 σ, `good`).
    /// A fit within noise needs no more shape, so the second look costs nothing there.
    pub(super) fn second_look(&mut self) -> Result<bool, CalibrateError> {
        let mut stalled: Vec<(usize, usize)> = Vec::new();
        for (ci, more) in std::mem::take(&mut self.stalled) {
            if self.frozen[ci]
                && self.level[ci] + more <= self.max_level[ci]
                && !stalled.iter().any(|(c, _)| *c == ci)
            {
                stalled.push((ci, more));
            }
        }
        if stalled.is_empty() {
            return Ok(false);
        }
        let rms_old = rms_of(&self.current, self.ctx)?;
        if within_noise(rms_old) {
            return Ok(false);
        }
        let mut groups = vec![stalled.clone()];
        if stalled.len() > 1 {
            groups.extend(stalled.iter().map(|&look| vec![look]));
        }
        for looks in groups {
            let more = |ci: usize| looks.iter().find(|(c, _)| *c == ci).map_or(0, |(_, m)| *m);
            let levels: Vec<usize> = (0..3).map(|ci| self.level[ci] + more(ci)).collect();
            let new_knots: Vec<(usize, Vec<f64>)> = looks
                .iter()
                .map(|&(ci, m)| (ci, knots(self.ranges[ci], self.level[ci] + m)))
                .collect();
            let grown = |base: &Shape| {
                new_knots
                    .iter()
                    .fold(base.clone(), |t, (ci, k)| t.resampled(*ci, k.clone()))
            };
            let mut trial = grown(&self.shape);
            let mut look = self.look(&trial, &levels, rms_old)?;
            // One component whose new knots leave some of its curves unidentified at the fitted
            // values: those held at their fit, as in a growth (on GSPy's generator unit with its
            // design GG speed written 9 831 rpm, the compressor's flow at 4 knots).
            let retry = match (&look, looks.as_slice()) {
                (Look::Unidentified(bad), [(ci, _)])
                    if self.may_hold && !bad.is_empty() && bad.len() < trial.curves[*ci].len() =>
                {
                    Some((*ci, bad.iter().map(|(_, c)| c.clone()).collect::<Vec<_>>()))
                }
                _ => None,
            };
            if let Some((ci, bad)) = retry {
                let why = format!(
                    "held at its fit with {} knot(s): {}, at the fitted values",
                    self.level[ci],
                    unresolved_at(levels[ci])
                );
                trial = grown(&self.shape.with_held(ci, &bad, &why));
                look = self.look(&trial, &levels, rms_old)?;
            }
            let Look::Kept(kept) = look else {
                continue;
            };
            let (fitted, keys, pass) = *kept;
            // The shape has changed under every component: one stopped before (its knots no
            // better, or not identified, beside the old shape) is tried again.
            // (One that looked and reached its most knots is unfrozen too, so that the next
            // growth's `freeze_full` states why it stops there.)
            for (ci, &level) in levels.iter().enumerate() {
                if !trial.curves[ci].is_empty() && (level < self.max_level[ci] || more(ci) > 0) {
                    self.frozen[ci] = false;
                    self.knots_reason[ci].clear();
                }
            }
            self.level = levels;
            self.design_free.retain(|k| pass.identifies(&keys, k));
            self.adopt(fitted, trial, &keys, &pass);
            return Ok(true);
        }
        for (ci, _) in stalled {
            self.knots_reason[ci].push_str(
                "; fitted with more (the fit not within noise), no better or not identified at \
                 the fitted values either (see the steps)",
            );
        }
        Ok(false)
    }

    /// One second look: `trial` (at knots `levels`) fitted from the current values, kept when
    /// the data's RMS falls by [`MIN_GAIN`] from `rms_old` and the identifiability analysis at
    /// the fitted values identifies every knot of the components that grew; else whether it
    /// gained, and if so which curves of those components the analysis does not identify.
    fn look(
        &mut self,
        trial: &Shape,
        levels: &[usize],
        rms_old: f64,
    ) -> Result<Look, CalibrateError> {
        let start = shaped(&self.current, trial)?;
        let mut keys: Vec<String> = self.design_free.clone();
        keys.extend(trial.keys());
        let Fitted {
            engine: fitted,
            runs: n,
            step,
            ..
        } = fit(&start, candidates_for(&start, &keys)?, trial, self.ctx)?;
        self.runs += n;
        let rms_new = rms_of(&fitted, self.ctx)?;
        if rms_new > rms_old * (1.0 - MIN_GAIN) {
            self.steps.push(format!(
                "knots {levels:?} (second look, the fit not within noise): {step}; data RMS \
                 {rms_old:.3} → {rms_new:.3} σ, not kept"
            ));
            return Ok(Look::NoGain);
        }
        let pass = identify_at(&fitted, &candidates_for(&fitted, &keys)?, self.ctx)?;
        self.runs += pass.runs;
        let mut bad: Vec<(usize, String)> = Vec::new();
        for (ci, level) in levels.iter().enumerate() {
            if *level == self.level[ci] {
                continue;
            }
            for (curve, values) in &trial.curves[ci] {
                if !(0..values.len())
                    .all(|i| pass.identifies(&keys, &key(COMPONENTS[ci], curve, i)))
                {
                    bad.push((ci, curve.clone()));
                }
            }
        }
        if !bad.is_empty() {
            self.steps.push(format!(
                "knots {levels:?} (second look, the fit not within noise): {step}; data RMS \
                 {rms_old:.3} → {rms_new:.3} σ, not every knot identified at the fitted values \
                 ({}), not kept",
                bad.iter()
                    .map(|(ci, curve)| format!("{} {curve}", COMPONENTS[*ci]))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
            return Ok(Look::Unidentified(bad));
        }
        self.steps.push(format!(
            "knots {levels:?} (second look, the fit not within noise: identified at the fitted \
             values): {step}; data RMS {rms_old:.3} → {rms_new:.3} σ"
        ));
        Ok(Look::Kept(Box::new((fitted, keys, pass))))
    }
}
