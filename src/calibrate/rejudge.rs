//! Identifiability judged a second time, at the first fit's values (see [`rejudge`]), and the
//! fit of the larger set it identifies when that is kept. Must not do I/O.

use super::candidates::Candidate;
use super::identify;
use super::problem::{CalibrationProblem, PreparedPoints};
use super::startup::RestReading;
use super::{fit_identified, identifiability, rms, CalibrateError, CalibrationSettings, LmFit};
use crate::engine::Engine;
use crate::optim::JacobianOptions;
use rayon::ThreadPool;

/// The identifiability judged again at the fitted values, and the fit of the larger set it
/// identifies, when it is kept.
pub(super) struct Rejudged {
    pub(super) adopted: Option<Adopted>,
    pub(super) runs: usize,
    /// What the second pass found and whether its fit was kept (`None`: nothing new).
    pub(super) note: Option<String>,
}

/// A larger identified set fitted from the first fit's values.
pub(super) struct Adopted {
    pub(super) verdicts: Vec<identify::Verdict>,
    pub(super) chosen: Vec<usize>,
    pub(super) fitted: Vec<f64>,
    pub(super) lm: LmFit,
}

/// Judges the candidates' identifiability again at the first fit's values `fitted` (`chosen`
/// fitted) and, when that identifies every candidate the first pass did and more, fits them
/// together from there; kept when the data's RMS residual falls.
///
/// Why: the first pass judges at the file's guesses, where the model can be tens of σ off a
/// foreign unit, and the verdict there is a threshold on the σ a candidate would have: on a
/// generator of pyCycle's maps (`tests/foreign_generator.rs`) the PT's design pressure ratio
/// sat at 13 % of its interval against the 12.5 % allowed, stayed at the file's value, and the
/// PT's adaptation curves bent to make up for it (−5 % flow, −3.7 % efficiency); at the
/// fitted values it is 8 %. Refitted with it, the interior loads left out were predicted at
/// 0.10 / 0.35 % (mean / worst) instead of 0.28 / 0.89 %.
pub(super) fn rejudge(
    engine: &Engine,
    prepared: &PreparedPoints,
    rest: &[RestReading],
    candidates: &[Candidate],
    (chosen, fitted): (&[usize], &[f64]),
    (settings, jac_opts, pool): (&CalibrationSettings, JacobianOptions, &ThreadPool),
) -> Result<Rejudged, CalibrateError> {
    let at_fit: Vec<Candidate> = candidates
        .iter()
        .zip(fitted)
        .map(|(c, &x)| Candidate {
            guess: x.clamp(c.lower, c.upper),
            ..c.clone()
        })
        .collect();
    let problem = CalibrationProblem::new(
        engine,
        prepared.points.clone(),
        rest.to_vec(),
        at_fit.clone(),
    )?;
    let x1 = problem.guesses();
    let r1 = problem.residuals_at(&x1)?;
    let verdicts = identifiability(&problem, &at_fit, (&x1, &r1), &jac_opts, pool, prepared);
    let now: Vec<usize> = (0..at_fit.len())
        .filter(|&j| verdicts[j].identifiable)
        .collect();
    let runs = problem.runs();
    if now.len() <= chosen.len() || !chosen.iter().all(|j| now.contains(j)) {
        return Ok(Rejudged {
            adopted: None,
            runs,
            note: None,
        });
    }
    let sub = CalibrationProblem::new(
        engine,
        prepared.points.clone(),
        rest.to_vec(),
        now.iter().map(|&j| at_fit[j].clone()).collect(),
    )?;
    let mut refitted = x1.clone();
    let lm = fit_identified(&sub, &now, &mut refitted, settings, jac_opts, pool)?;
    let before = rms(&r1);
    let after = rms(&problem.residuals_at(&refitted)?);
    let runs = problem.runs() + lm.runs;
    let added: Vec<&str> = now
        .iter()
        .filter(|j| !chosen.contains(j))
        .map(|&j| at_fit[j].key.as_str())
        .collect();
    let note = format!(
        "identifiability judged again at the fitted values also identifies {}: fitted with \
         the others, data RMS {before:.2} → {after:.2} σ, {}",
        added.join(", "),
        if after < before { "kept" } else { "not kept" }
    );
    Ok(Rejudged {
        note: Some(note),
        adopted: (after < before).then_some(Adopted {
            verdicts,
            chosen: now,
            fitted: refitted,
            lm,
        }),
        runs,
    })
}
