//! Hidden truths on the instrument side: the recorded signals altered after the plant's
//! simulation (the plant itself is the core model).
//!
//! - `t34_two_path` / `t2_two_path`: a thermocouple with a junction path (2–6 s) and a shield
//!   path (10–25 s), 60/40 — against the library's single first-order `sensor_lag`. Magnitude:
//!   the mean time constant 0.6·τ₁ + 0.4·τ₂.
//! - `p2_bias` / `t34_bias`: 0.8–1.5 % of full scale (2500 kPa, 1200 K). Magnitude: the offset.
//! - `fuel_lead`: the recorded fuel flow leads the fuel burnt by a pure delay of 0.8–3 s —
//!   against the library's Erlang-chain-plus-lag `fuel_system`. Magnitude: the delay.
//! - `p34_ripple`: a 0.2 Hz ripple of 1.5–3 % on P34 (not in the library). Magnitude: the
//!   relative amplitude.
//!
//! Input channels (issue 23 item 5, the signals that drive the model; `bench gap --kinds`
//! only, not in the default cycle): `fuel_scale` (the fuel meter reads 1.5–4 % high or low),
//! `fuel_drift` (a meter drifting from 0 to 2–5 % through the start-up: not the library's
//! constant factor), `t1_offset` (T1 reads 1.5–4 K high or low), `p1_offset` (P1 off by
//! 0.5–1.5 kPa), `power_scale` (a power transducer ratio 1–3 % off), `fuel_cutoff` (the fuel
//! meter reads 3–8 g/s high or low, and the control system shows 0 below a low-flow cut-off of
//! 9–12 g/s: the zero is hidden at rest, and the light-off's first fuel is cut, against the
//! library's offset fading in over the first flow). Magnitude: the relative error, or the offset
//! in K / kPa / kg/s.
//!
//! Pure: no I/O.

use crate::diagnosis::DiagnosisError;
use crate::recording::Recording;
use crate::signals::Signal;
use rand::Rng;

/// A drawn alteration of the recorded signals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Alteration {
    /// Junction (τ₁) and shield (τ₂) paths, weighted 60/40.
    TwoPath {
        signal: Signal,
        tau1_s: f64,
        tau2_s: f64,
    },
    Offset {
        signal: Signal,
        offset: f64,
    },
    /// The record at t shows the flow burnt at t + `lead_s`.
    FuelLead {
        lead_s: f64,
    },
    /// Multiplicative ripple of relative amplitude `amplitude` at `hz`.
    Ripple {
        signal: Signal,
        amplitude: f64,
        hz: f64,
    },
    /// The instrument reads `factor` × the true value.
    Scale {
        signal: Signal,
        factor: f64,
    },
    /// The instrument's factor drifts linearly from 1 at the record's start to `1 + rel_end`
    /// at its end.
    Drift {
        signal: Signal,
        rel_end: f64,
    },
    /// The fuel meter reads `offset_kg_s` more than flows; the control system shows 0 where
    /// that reading is below `cutoff_kg_s`.
    FuelCutoff {
        offset_kg_s: f64,
        cutoff_kg_s: f64,
    },
}

/// A random sign.
fn sign(rng: &mut impl Rng) -> f64 {
    if rng.random_bool(0.5) {
        1.0
    } else {
        -1.0
    }
}

impl Alteration {
    /// The same alteration with its error's size times `share` (an error that has grown to that
    /// share of its size; a lag or a lead, which has no size, as it is).
    pub(crate) fn scaled(self, share: f64) -> Alteration {
        match self {
            Alteration::Offset { signal, offset } => Alteration::Offset {
                signal,
                offset: offset * share,
            },
            Alteration::Ripple {
                signal,
                amplitude,
                hz,
            } => Alteration::Ripple {
                signal,
                amplitude: amplitude * share,
                hz,
            },
            Alteration::Scale { signal, factor } => Alteration::Scale {
                signal,
                factor: 1.0 + (factor - 1.0) * share,
            },
            Alteration::Drift { signal, rel_end } => Alteration::Drift {
                signal,
                rel_end: rel_end * share,
            },
            Alteration::FuelCutoff {
                offset_kg_s,
                cutoff_kg_s,
            } => Alteration::FuelCutoff {
                offset_kg_s: offset_kg_s * share,
                cutoff_kg_s,
            },
            Alteration::TwoPath { .. } | Alteration::FuelLead { .. } => self,
        }
    }

    /// Draws the alteration of instrument truth `kind`, with its magnitude; `None` for a kind
    /// that is not an instrument truth.
    pub(crate) fn draw(kind: &str, rng: &mut impl Rng) -> Option<(Alteration, f64)> {
        Some(match kind {
            "t34_two_path" | "t2_two_path" => {
                let signal = if kind == "t34_two_path" {
                    Signal::T34
                } else {
                    Signal::T2
                };
                let (t1, t2) = (rng.random_range(2.0..6.0), rng.random_range(10.0..25.0));
                (
                    Alteration::TwoPath {
                        signal,
                        tau1_s: t1,
                        tau2_s: t2,
                    },
                    0.6 * t1 + 0.4 * t2,
                )
            }
            "p2_bias" | "t34_bias" => {
                let (signal, full_scale) = if kind == "p2_bias" {
                    (Signal::P2, 2500.0)
                } else {
                    (Signal::T34, 1200.0)
                };
                let offset = rng.random_range(0.008..0.015) * full_scale;
                (Alteration::Offset { signal, offset }, offset)
            }
            "fuel_lead" => {
                let lead_s = rng.random_range(0.8..3.0);
                (Alteration::FuelLead { lead_s }, lead_s)
            }
            "p34_ripple" => {
                let amplitude = rng.random_range(0.015..0.03);
                (
                    Alteration::Ripple {
                        signal: Signal::P34,
                        amplitude,
                        hz: 0.2,
                    },
                    amplitude,
                )
            }
            "fuel_scale" | "power_scale" => {
                let (signal, lo, hi) = if kind == "fuel_scale" {
                    (Signal::FuelFlow, 0.015, 0.04)
                } else {
                    (Signal::Power, 0.01, 0.03)
                };
                let rel = sign(rng) * rng.random_range(lo..hi);
                (
                    Alteration::Scale {
                        signal,
                        factor: 1.0 + rel,
                    },
                    rel,
                )
            }
            "fuel_drift" => {
                let rel_end = rng.random_range(0.02..0.05);
                (
                    Alteration::Drift {
                        signal: Signal::FuelFlow,
                        rel_end,
                    },
                    rel_end,
                )
            }
            "t1_offset" | "p1_offset" => {
                let (signal, lo, hi) = if kind == "t1_offset" {
                    (Signal::T1, 1.5, 4.0)
                } else {
                    (Signal::P1, 0.5, 1.5)
                };
                let offset = sign(rng) * rng.random_range(lo..hi);
                (Alteration::Offset { signal, offset }, offset)
            }
            "fuel_cutoff" => {
                let offset_kg_s = sign(rng) * rng.random_range(0.003..0.008);
                (
                    Alteration::FuelCutoff {
                        offset_kg_s,
                        cutoff_kg_s: rng.random_range(0.009..0.012),
                    },
                    offset_kg_s,
                )
            }
            _ => return None,
        })
    }

    /// Applies the alteration to `rec`.
    pub(crate) fn apply(&self, rec: &mut Recording) -> Result<(), DiagnosisError> {
        match *self {
            Alteration::TwoPath {
                signal,
                tau1_s,
                tau2_s,
            } => two_path(rec, signal, tau1_s, tau2_s),
            Alteration::Offset { signal, offset } => {
                for k in 0..rec.len() {
                    if let Some(v) = rec.value(k, signal) {
                        rec.set(k, signal, v + offset)?;
                    }
                }
                Ok(())
            }
            Alteration::FuelLead { lead_s } => {
                let t = rec.times().to_vec();
                let f = rec.series(Signal::FuelFlow);
                for k in 0..t.len() {
                    let tt = t[k] + lead_s;
                    let j = t.partition_point(|&x| x <= tt).clamp(1, t.len() - 1);
                    let w = ((tt - t[j - 1]) / (t[j] - t[j - 1])).clamp(0.0, 1.0);
                    let v = f[j - 1] + w * (f[j] - f[j - 1]);
                    if v.is_finite() {
                        rec.set(k, Signal::FuelFlow, v)?;
                    }
                }
                Ok(())
            }
            Alteration::Ripple {
                signal,
                amplitude,
                hz,
            } => {
                let t = rec.times().to_vec();
                for (k, &tt) in t.iter().enumerate() {
                    if let Some(v) = rec.value(k, signal) {
                        let r = 1.0 + amplitude * (2.0 * std::f64::consts::PI * hz * tt).sin();
                        rec.set(k, signal, v * r)?;
                    }
                }
                Ok(())
            }
            Alteration::Scale { signal, factor } => {
                for k in 0..rec.len() {
                    if let Some(v) = rec.value(k, signal) {
                        rec.set(k, signal, v * factor)?;
                    }
                }
                Ok(())
            }
            Alteration::Drift { signal, rel_end } => {
                let t = rec.times().to_vec();
                let (t0, t1) = (t[0], t[t.len() - 1]);
                let span = (t1 - t0).max(1e-9);
                for (k, &tt) in t.iter().enumerate() {
                    if let Some(v) = rec.value(k, signal) {
                        rec.set(k, signal, v * (1.0 + rel_end * (tt - t0) / span))?;
                    }
                }
                Ok(())
            }
            Alteration::FuelCutoff {
                offset_kg_s,
                cutoff_kg_s,
            } => {
                for k in 0..rec.len() {
                    if let Some(v) = rec.value(k, Signal::FuelFlow) {
                        let read = v + offset_kg_s;
                        rec.set(
                            k,
                            Signal::FuelFlow,
                            if read < cutoff_kg_s { 0.0 } else { read },
                        )?;
                    }
                }
                Ok(())
            }
        }
    }
}

fn two_path(rec: &mut Recording, s: Signal, tau1: f64, tau2: f64) -> Result<(), DiagnosisError> {
    let t = rec.times().to_vec();
    let x = rec.series(s);
    let (mut y1, mut y2) = (f64::NAN, f64::NAN);
    for k in 0..t.len() {
        if !x[k].is_finite() {
            continue;
        }
        if y1.is_nan() {
            (y1, y2) = (x[k], x[k]);
        } else {
            let dt = t[k] - t[k - 1];
            let (a1, a2) = ((-dt / tau1).exp(), (-dt / tau2).exp());
            y1 = a1 * y1 + (1.0 - a1) * x[k];
            y2 = a2 * y2 + (1.0 - a2) * x[k];
        }
        rec.set(k, s, 0.6 * y1 + 0.4 * y2)?;
    }
    Ok(())
}
