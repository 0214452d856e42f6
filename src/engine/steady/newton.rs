//! The steady solve's iteration: Newton's method on the used residuals over the free unknowns,
//! its Jacobian by finite differences at the first iterate and by Broyden's rank-one updates
//! after, each step backtracked until it lowers the residual norm (the parent module decides
//! where it starts and how far-off demands are reached). Must not do I/O or hold state between
//! solves.

use super::{
    evaluate, fix_demand, layout, Evaluated, SolveStats, SteadyInputs, SteadyPoint, Unknowns,
};
use crate::engine::model::Model;
use nalgebra::{DMatrix, DVector};

fn norm(r: &[f64], rows: &[usize]) -> f64 {
    rows.iter().map(|&i| r[i] * r[i]).sum::<f64>().sqrt()
}

fn valid(x: &Unknowns, model: &Model, inp: &SteadyInputs) -> bool {
    x.0[0] > 0.05
        && (-1.0..=2.0).contains(&x.0[1])
        && x.0[2] * model.consts.p34_design_kpa > inp.p_amb_kpa * 1.0005
        && x.0[3] > 0.0
        && x.0.iter().all(|v| v.is_finite())
}

/// Residual norm below which a steady point is converged.
const CONVERGED: f64 = 1e-11;
/// Residual norm Broyden's iterations go on towards while a whole step still lowers the norm
/// (one evaluation each). Why: Newton's last step, quadratic, used to land far below
/// [`CONVERGED`]; Broyden's, superlinear, stops just under it, and a calibration's
/// finite-difference Jacobian (steps of 1e-3 of an interval) then read that noise: the
/// continuation-shaped adaptation of a foreign unit predicted its left-out full load 0.53 %
/// off (worst signal 1.02 %); polished, 0.37 % (0.81 %), as with Newton's full Jacobians
/// (0.39 %, 0.80 %).
const POLISHED: f64 = 1e-14;

/// Newton iteration from `x0`; returns the converged unknowns.
pub(super) fn newton(
    model: &Model,
    inp: &SteadyInputs,
    x0: Unknowns,
    stats: &mut SolveStats,
) -> Result<Unknowns, String> {
    newton_at(model, inp, x0, stats).map(|(x, _)| x)
}

/// [`newton`], with the point at the converged unknowns (evaluated there on the way).
///
/// The Jacobian is taken by finite differences at the first iterate only; each step taken then
/// updates it by Broyden's rank-one rule (the residuals' change along the step), and a step the
/// updated Jacobian cannot make descend is retried on a fresh finite-difference one. Why: a
/// finite-difference Jacobian costs one gas-path evaluation per free unknown, so a warm start
/// needing three iterations spent 13–16 evaluations on what Broyden's iterations, one
/// evaluation each, finish in about half (`gtwatch bench steady`); the steady solve is most of
/// a calibration's and a snapshot diagnosis's time. The stopping rule is the same, so the point
/// is the same within its tolerance.
pub(super) fn newton_at(
    model: &Model,
    inp: &SteadyInputs,
    x0: Unknowns,
    stats: &mut SolveStats,
) -> Result<(Unknowns, SteadyPoint), String> {
    let (free, rows) = layout(inp.demand);
    let mut x = x0;
    fix_demand(model, inp.demand, &mut x);
    let mut ev = evaluate(model, inp, &x);
    stats.evaluations += 1;
    let mut f = norm(&ev.residuals, rows);
    let mut updated: Option<DMatrix<f64>> = None;
    for _iter in 0..60 {
        if f < POLISHED {
            return Ok((x, ev.point));
        }
        stats.newton_iterations += 1;
        let (jac, fresh) = match updated.take() {
            Some(j) => (j, false),
            None => (fd_jacobian(model, inp, &x, &ev, stats), true),
        };
        // Once converged, a step is only tried whole: where it no longer lowers the norm the
        // point is as good as the arithmetic allows.
        let halvings = if f < CONVERGED { 0 } else { 30 };
        match descend(model, inp, (&x, &ev, f), &jac, halvings, stats) {
            Ok((xn, evn, fnew)) => {
                // Broyden: J += (Δr − J·s) sᵀ / (sᵀ s) for the step s taken.
                let s = DVector::from_iterator(free.len(), free.iter().map(|&k| xn.0[k] - x.0[k]));
                let dr = DVector::from_iterator(
                    rows.len(),
                    rows.iter().map(|&r| evn.residuals[r] - ev.residuals[r]),
                );
                let ss = s.dot(&s);
                let mut jac = jac;
                if ss > 0.0 {
                    let miss = dr - &jac * &s;
                    jac += miss * s.transpose() / ss;
                }
                updated = Some(jac);
                x = xn;
                ev = evn;
                f = fnew;
            }
            Err(_) if f < CONVERGED => return Ok((x, ev.point)),
            Err(e) if fresh => return Err(e),
            // The updated Jacobian led nowhere: the next iteration takes a fresh one here.
            Err(_) => {}
        }
    }
    if f < 1e-9 {
        Ok((x, ev.point))
    } else {
        Err(format!(
            "no convergence after 60 iterations (residual norm {f:.3e})"
        ))
    }
}

/// The Jacobian of the used residuals over the free unknowns at `x` (residuals `ev`), by
/// forward differences.
fn fd_jacobian(
    model: &Model,
    inp: &SteadyInputs,
    x: &Unknowns,
    ev: &Evaluated,
    stats: &mut SolveStats,
) -> DMatrix<f64> {
    let (free, rows) = layout(inp.demand);
    let n = free.len();
    let mut jac = DMatrix::<f64>::zeros(rows.len(), n);
    for (j, &k) in free.iter().enumerate() {
        let h = 1e-7 * x.0[k].abs().max(1e-2);
        let mut xp = *x;
        xp.0[k] += h;
        let evp = evaluate(model, inp, &xp);
        stats.evaluations += 1;
        for (i, &r) in rows.iter().enumerate() {
            jac[(i, j)] = (evp.residuals[r] - ev.residuals[r]) / h;
        }
    }
    jac
}

/// One Newton step on `jac` from `(x, its residuals, their norm)`, backtracking: the largest
/// step that keeps the point valid and lowers the residual norm, with the point there.
fn descend(
    model: &Model,
    inp: &SteadyInputs,
    (x, ev, f): (&Unknowns, &Evaluated, f64),
    jac: &DMatrix<f64>,
    halvings: usize,
    stats: &mut SolveStats,
) -> Result<(Unknowns, Evaluated, f64), String> {
    let (free, rows) = layout(inp.demand);
    let rhs = DVector::from_iterator(rows.len(), rows.iter().map(|&r| -ev.residuals[r]));
    let dx = jac
        .clone()
        .lu()
        .solve(&rhs)
        .ok_or("singular Jacobian (no unique operating point)")?;
    let mut lambda = 1.0;
    for _ in 0..=halvings {
        let mut xn = *x;
        for (j, &k) in free.iter().enumerate() {
            xn.0[k] += lambda * dx[j];
        }
        if valid(&xn, model, inp) {
            let evn = evaluate(model, inp, &xn);
            stats.evaluations += 1;
            let fnew = norm(&evn.residuals, rows);
            if fnew.is_finite() && fnew < f {
                return Ok((xn, evn, fnew));
            }
        }
        lambda *= 0.5;
    }
    Err(format!("Newton stalled with residual norm {f:.3e}"))
}
