//! Gas properties of dry air and lean combustion products of methane or another fuel.
//!
//! What it is for: `cp`, `cv`, `R`, `γ`, sensible enthalpy `h` and the entropy function `φ`
//! (and their inverses) as functions of temperature and fuel-air ratio, for the engine model.
//! What it must not do: I/O, allocation, globals other than `const`s. Every call is a few
//! polynomial evaluations (tens of nanoseconds); the dynamic model calls these millions of
//! times per simulated start-up.
//!
//! # Data
//!
//! NASA 7-coefficient polynomials of N2, O2, Ar, CO2 and H2O exactly as in Cantera's
//! `gri30.yaml` (GRI-Mech 3.0 thermodynamics), with Cantera's atomic weights (H 1.008,
//! C 12.011, N 14.007, O 15.999, Ar 39.95) and gas constant 8314.462618 J/(kmol K).
//!
//! Dry air is N2 0.78084, O2 0.20946, Ar 0.00934, CO2 0.00036 by mole (M = 28.96573 kg/kmol,
//! R = 287.0448 J/(kg K)): the composition the project's Cantera reference file
//! (`shared/reference/gas_properties_cantera.csv`) was computed with.
//!
//! Combustion products are those of complete lean combustion CH4 + 2 O2 -> CO2 + 2 H2O at
//! fuel-air ratio `far` (kg fuel / kg dry air). Per kilogram of mixture the composition is
//! `(y_air + far · Δ) / (1 + far)` with `Δ` the species change per kilogram of fuel; every
//! property coefficient is linear in the composition, so [`Gas::products`] mixes two
//! precomputed coefficient sets (`AIR`, `DELTA`, both `const`). `far` is clamped to
//! `0 ..= FAR_MAX` (0.068). Stoichiometric is about 0.0580; above it the lean-product formula is
//! simply continued (O2 fraction slightly negative, CO/H2 of rich combustion not modelled) so
//! that a solver stepping past stoichiometric sees continuous properties.
//!
//! # Reference state
//!
//! `h` is the *sensible* enthalpy of the mixture relative to the same mixture at
//! [`T_REF_K`] = 288.15 K: `h(288.15 K) = 0` for every `far`. `φ(T) = s°(T) − s°(288.15 K)` is the
//! standard-state (pressure-independent) entropy function, so an isentropic change satisfies
//! `φ(T_out) = φ(T_in) + R ln(p_out/p_in)`.
//!
//! Heat of combustion is *not* in these enthalpies: it enters the combustor energy balance
//! through the fuel's lower heating value at 288.15 K and its sensible enthalpy `h_f` at its
//! supply temperature (both from [`Fuel`]; 0 for fuel supplied at 288.15 K):
//! `(W_air + W_fuel) · h_products(T3) = W_air · h_air(T2) + W_fuel · (η_b · LHV + h_f)`.
//!
//! # Other fuels
//!
//! [`Fuel`] (`fuel.rs`) describes a gas fuel by its mole fractions (CH4, C2H6, C3H8, C4H10, N2,
//! CO2, H2) or a liquid by its H/C ratio: it computes the LHV, the fuel's sensible enthalpy and
//! its own per-kg-fuel change `Δ`, and [`Fuel::products`] mixes it with `AIR` exactly as
//! [`Gas::products`] does for methane. Species data: `species.rs`.
//!
//! # Range
//!
//! Checked against Cantera from 200 K to 2200 K. The NASA polynomials switch range at
//! 1000 K; `cp` has a jump there of under 0.001 J/(kg K) (as in Cantera), while the high-range
//! integration constants are shifted by under 0.2 J/kg (h) and 0.001 J/(kg K) (φ) so that `h` and
//! `φ` are exactly continuous at 1000 K and the Newton inverses cannot oscillate across a gap.
//! Outside 200 K ..= 3500 K (the polynomials' fitted range) `cp` is held at its end value and
//! `h`, `φ` continue continuously with that constant `cp`; the useful range is 150–2500 K.

/// Reference temperature of `h` and `φ`, and of the LHV: 288.15 K (ISO).
pub const T_REF_K: f64 = 288.15;

/// Largest fuel-air ratio accepted by [`Gas::products`] (values above are clamped).
pub const FAR_MAX: f64 = 0.068;

/// Universal gas constant as used by Cantera, J/(kmol K).
const R_UNIVERSAL: f64 = 8314.462618;

/// Temperature where the NASA polynomials switch from the low to the high range.
const T_MID: f64 = 1000.0;
/// Below this `cp` is held constant.
const T_EXT_LO: f64 = 200.0;
/// Above this `cp` is held constant.
const T_EXT_HI: f64 = 3500.0;

// ln of the fixed temperatures (f64::ln is not const); a test checks them.
const LN_T_REF: f64 = 5.663481177882676;
const LN_T_MID: f64 = 6.907755278982137;
const LN_T_EXT_LO: f64 = 5.298317366548036;
const LN_T_EXT_HI: f64 = 8.160518247477505;

mod fuel;
mod species;
pub use fuel::{
    Fuel, FuelError, VolumeBasis, COMPOSITION_SUM_TOLERANCE, FUEL_T_MAX_K, FUEL_T_MIN_K,
    GAS_FUEL_SPECIES, LIQUID_CP_J_PER_KG_K,
};
use species::*;

/// Dry-air mole fractions N2, O2, Ar, CO2 (sum 1).
const X_AIR: [f64; 4] = [0.78084, 0.20946, 0.00934, 0.00036];
const M_AIR: f64 = X_AIR[0] * W_N2 + X_AIR[1] * W_O2 + X_AIR[2] * W_AR + X_AIR[3] * W_CO2;

/// Mass fractions of N2, O2, Ar, CO2, H2O in dry air.
const Y_AIR: [f64; 5] = [
    X_AIR[0] * W_N2 / M_AIR,
    X_AIR[1] * W_O2 / M_AIR,
    X_AIR[2] * W_AR / M_AIR,
    X_AIR[3] * W_CO2 / M_AIR,
    0.0,
];
/// Change of species mass per kg of methane burnt: CH4 + 2 O2 -> CO2 + 2 H2O.
const Y_DELTA: [f64; 5] = [
    0.0,
    -2.0 * W_O2 / W_CH4,
    0.0,
    W_CO2 / W_CH4,
    2.0 * W_H2O / W_CH4,
];

/// Property coefficients on a mass basis; every field is linear in the composition.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Coeffs {
    /// Gas constant, J/(kg K).
    r: f64,
    /// cp = c0 + c1 T + ... + c4 T⁴, J/(kg K); `[low range, high range]`.
    cp: [[f64; 5]; 2],
    /// h = T (h0 + T (h1 + ... T h4)) + h5, J/kg, referenced to 288.15 K.
    h: [[f64; 6]; 2],
    /// φ = s0 ln T + T (s1 + T (s2 + T (s3 + T s4))) + s5, J/(kg K), referenced to 288.15 K.
    s: [[f64; 6]; 2],
    /// cp, h, φ at T_EXT_LO (constant-cp extension below).
    ext_lo: [f64; 3],
    /// cp, h, φ at T_EXT_HI (constant-cp extension above).
    ext_hi: [f64; 3],
}

const fn poly_cp(c: &[f64; 5], t: f64) -> f64 {
    c[0] + t * (c[1] + t * (c[2] + t * (c[3] + t * c[4])))
}
const fn poly_h(c: &[f64; 6], t: f64) -> f64 {
    t * (c[0] + t * (c[1] + t * (c[2] + t * (c[3] + t * c[4])))) + c[5]
}
const fn poly_s(c: &[f64; 6], t: f64, ln_t: f64) -> f64 {
    c[0] * ln_t + t * (c[1] + t * (c[2] + t * (c[3] + t * c[4]))) + c[5]
}

/// Coefficients of a composition given by mass fractions (N2, O2, Ar, CO2, H2O); the mass
/// fractions need not sum to one (used for the per-kg-fuel change `DELTA`). Everything here is
/// linear in `y`, which is what makes `Gas::products` a plain linear mix.
const fn derive(y: [f64; 5]) -> Coeffs {
    let species = [&N2, &O2, &AR, &CO2, &H2O];
    let mut raw = [[0.0f64; 7]; 2];
    let mut r = 0.0;
    let mut k = 0;
    while k < 5 {
        let rk = R_UNIVERSAL / species[k].w;
        r += y[k] * rk;
        let mut i = 0;
        while i < 7 {
            raw[0][i] += y[k] * rk * species[k].lo[i];
            raw[1][i] += y[k] * rk * species[k].hi[i];
            i += 1;
        }
        k += 1;
    }
    let mut cp = [[0.0f64; 5]; 2];
    let mut h = [[0.0f64; 6]; 2];
    let mut s = [[0.0f64; 6]; 2];
    let mut j = 0;
    while j < 2 {
        let a = raw[j];
        cp[j] = [a[0], a[1], a[2], a[3], a[4]];
        h[j] = [a[0], a[1] / 2.0, a[2] / 3.0, a[3] / 4.0, a[4] / 5.0, a[5]];
        s[j] = [a[0], a[1], a[2] / 2.0, a[3] / 3.0, a[4] / 4.0, a[6]];
        j += 1;
    }
    // Reference both ranges to 288.15 K through the low range...
    let h_ref = poly_h(&h[0], T_REF_K);
    let s_ref = poly_s(&s[0], T_REF_K, LN_T_REF);
    h[0][5] -= h_ref;
    s[0][5] -= s_ref;
    // ...and shift the high range so h and φ are exactly continuous at 1000 K.
    h[1][5] += poly_h(&h[0], T_MID) - poly_h(&h[1], T_MID);
    s[1][5] += poly_s(&s[0], T_MID, LN_T_MID) - poly_s(&s[1], T_MID, LN_T_MID);
    let ext_lo = [
        poly_cp(&cp[0], T_EXT_LO),
        poly_h(&h[0], T_EXT_LO),
        poly_s(&s[0], T_EXT_LO, LN_T_EXT_LO),
    ];
    let ext_hi = [
        poly_cp(&cp[1], T_EXT_HI),
        poly_h(&h[1], T_EXT_HI),
        poly_s(&s[1], T_EXT_HI, LN_T_EXT_HI),
    ];
    Coeffs {
        r,
        cp,
        h,
        s,
        ext_lo,
        ext_hi,
    }
}

/// Coefficients per kg of dry air.
const AIR: Coeffs = derive(Y_AIR);
/// Change of the coefficients per kg of methane burnt (not normalised).
const DELTA: Coeffs = derive(Y_DELTA);

#[inline]
fn mix<const N: usize>(a: &[f64; N], d: &[f64; N], far: f64, inv: f64) -> [f64; N] {
    let mut out = [0.0; N];
    for i in 0..N {
        out[i] = (a[i] + far * d[i]) * inv;
    }
    out
}

/// Thermodynamic properties of one gas composition (dry air, or methane combustion products at
/// one fuel-air ratio). Cheap to copy (~50 f64); build it once per composition change.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gas {
    far: f64,
    c: Coeffs,
}

impl Gas {
    /// Dry air (`far` = 0), as a constant.
    pub const AIR: Gas = Gas { far: 0.0, c: AIR };

    /// Dry air (`far` = 0).
    pub fn air() -> Gas {
        Gas::AIR
    }

    /// Products of complete lean combustion of methane in dry air at fuel-air ratio `far`
    /// (kg fuel / kg air), clamped to `0 ..= FAR_MAX`. `products(0.0)` equals `air()`. Other
    /// fuels: [`Fuel::products`].
    pub fn products(far: f64) -> Gas {
        Gas::mixed(&DELTA, far)
    }

    /// Air plus `far` times the per-kg-fuel change `d`, per kg of mixture.
    #[inline]
    fn mixed(d: &Coeffs, far: f64) -> Gas {
        let far = if far.is_nan() {
            0.0
        } else {
            far.clamp(0.0, FAR_MAX)
        };
        let inv = 1.0 / (1.0 + far);
        let a = &AIR;
        Gas {
            far,
            c: Coeffs {
                r: (a.r + far * d.r) * inv,
                cp: [
                    mix(&a.cp[0], &d.cp[0], far, inv),
                    mix(&a.cp[1], &d.cp[1], far, inv),
                ],
                h: [
                    mix(&a.h[0], &d.h[0], far, inv),
                    mix(&a.h[1], &d.h[1], far, inv),
                ],
                s: [
                    mix(&a.s[0], &d.s[0], far, inv),
                    mix(&a.s[1], &d.s[1], far, inv),
                ],
                ext_lo: mix(&a.ext_lo, &d.ext_lo, far, inv),
                ext_hi: mix(&a.ext_hi, &d.ext_hi, far, inv),
            },
        }
    }

    /// Fuel-air ratio of this composition (after clamping).
    pub fn far(&self) -> f64 {
        self.far
    }

    /// Specific gas constant, J/(kg K).
    #[inline]
    pub fn r(&self) -> f64 {
        self.c.r
    }

    /// Specific heat at constant pressure, J/(kg K).
    #[inline]
    pub fn cp(&self, t_k: f64) -> f64 {
        if t_k < T_EXT_LO {
            self.c.ext_lo[0]
        } else if t_k < T_MID {
            poly_cp(&self.c.cp[0], t_k)
        } else if t_k <= T_EXT_HI {
            poly_cp(&self.c.cp[1], t_k)
        } else {
            self.c.ext_hi[0]
        }
    }

    /// Specific heat at constant volume, J/(kg K).
    #[inline]
    pub fn cv(&self, t_k: f64) -> f64 {
        self.cp(t_k) - self.c.r
    }

    /// Ratio of specific heats cp/cv.
    #[inline]
    pub fn gamma(&self, t_k: f64) -> f64 {
        let cp = self.cp(t_k);
        cp / (cp - self.c.r)
    }

    /// Sensible enthalpy relative to 288.15 K, J/kg (exactly 0 at 288.15 K for every `far`).
    #[inline]
    pub fn h(&self, t_k: f64) -> f64 {
        if t_k < T_EXT_LO {
            self.c.ext_lo[1] + self.c.ext_lo[0] * (t_k - T_EXT_LO)
        } else if t_k < T_MID {
            poly_h(&self.c.h[0], t_k)
        } else if t_k <= T_EXT_HI {
            poly_h(&self.c.h[1], t_k)
        } else {
            self.c.ext_hi[1] + self.c.ext_hi[0] * (t_k - T_EXT_HI)
        }
    }

    /// Entropy function `s°(T) − s°(288.15 K)`, J/(kg K).
    #[inline]
    pub fn phi(&self, t_k: f64) -> f64 {
        self.phi_ln(t_k, t_k.ln())
    }

    /// `phi` with ln T supplied by the caller (the inverse iterates in ln T).
    #[inline]
    fn phi_ln(&self, t_k: f64, ln_t: f64) -> f64 {
        if t_k < T_EXT_LO {
            self.c.ext_lo[2] + self.c.ext_lo[0] * (ln_t - LN_T_EXT_LO)
        } else if t_k < T_MID {
            poly_s(&self.c.s[0], t_k, ln_t)
        } else if t_k <= T_EXT_HI {
            poly_s(&self.c.s[1], t_k, ln_t)
        } else {
            self.c.ext_hi[2] + self.c.ext_hi[0] * (ln_t - LN_T_EXT_HI)
        }
    }

    /// Temperature with sensible enthalpy `h` (J/kg): Newton on `h(T) − h = 0` with `dh/dT = cp`,
    /// started from a mean-cp guess; converges to a relative error far below 1e-10 in 2–4 steps.
    pub fn t_from_h(&self, h: f64) -> f64 {
        // Mean cp between 288 K and T rises from ~1005 to ~1200 J/(kg K) for air up to 2000 K.
        let cp_guess = 1004.0 + 1.0e-4 * h.max(0.0);
        let mut t = (T_REF_K + h / cp_guess).max(20.0);
        for _ in 0..40 {
            let dt = (self.h(t) - h) / self.cp(t);
            let t_new = (t - dt).max(0.5 * t);
            // Newton's error after a step is O(step²/T): a step below 3e-6 T leaves < 1e-11 T,
            // so stop there rather than spend one more evaluation confirming it.
            if (t_new - t).abs() <= 3e-6 * t {
                return t_new;
            }
            t = t_new;
        }
        t
    }

    /// [`Gas::t_from_h`] started from a nearby temperature `t0` whose enthalpy `h0 = h(t0)` the
    /// caller already has (a machine's exit from its isentropic exit state): the first Newton
    /// step costs no enthalpy evaluation, and the start is close, so one more step usually
    /// meets the same convergence test as [`Gas::t_from_h`].
    #[inline]
    pub fn t_from_h_near(&self, h: f64, t0: f64, h0: f64) -> f64 {
        let (mut t, mut h_t) = (t0, h0);
        for _ in 0..40 {
            let dt = (h_t - h) / self.cp(t);
            let t_new = (t - dt).max(0.5 * t);
            if (t_new - t).abs() <= 3e-6 * t {
                return t_new;
            }
            t = t_new;
            h_t = self.h(t);
        }
        t
    }

    /// Temperature with entropy function `phi` (J/(kg K)): Newton in x = ln T, where
    /// `dφ/dx = cp`, so the iteration is nearly linear and cannot leave T > 0.
    pub fn t_from_phi(&self, phi: f64) -> f64 {
        let cp_guess = 1004.0 + 0.12 * phi.max(0.0);
        self.solve_phi(phi, LN_T_REF + phi / cp_guess)
    }

    /// Outlet temperature of an isentropic change by pressure ratio `pr = p_out/p_in`
    /// (> 1 compression, < 1 expansion): `φ(T_out) = φ(T_in) + R ln(pr)`.
    pub fn isentropic_t(&self, t_in: f64, pr: f64) -> f64 {
        let ln_t_in = t_in.ln();
        let d_phi = self.c.r * pr.ln();
        let target = self.phi_ln(t_in, ln_t_in) + d_phi;
        // Guess from constant cp at the inlet: ln T_out = ln T_in + R ln(pr) / cp.
        let cp_in = self.cp(t_in);
        let cp_guess = if pr > 1.0 {
            cp_in * 1.03
        } else {
            cp_in * 0.985
        };
        self.solve_phi(target, ln_t_in + d_phi / cp_guess)
    }

    fn solve_phi(&self, target: f64, x0: f64) -> f64 {
        let mut x = x0;
        let mut t = x0.exp();
        for _ in 0..40 {
            let dx = (self.phi_ln(t, x) - target) / self.cp(t);
            x -= dx;
            // Once the step is small, T follows x as T·e^(−dx) by a short series instead of a
            // fresh exp (most of a call's cost): for |dx| < 1e-2 the series' error, dx⁷/5040,
            // is below one ulp. The first step from the constant-cp guess is usually that small.
            t = if dx.abs() < 1e-2 {
                t * exp_small(-dx)
            } else {
                x.exp()
            };
            // Error after a step is O(dx²): |dx| < 3e-6 leaves a relative T error < 1e-11.
            if dx.abs() <= 3e-6 {
                break;
            }
        }
        t
    }
}

/// e^d for |d| < 1e-2 (the Taylor series to d⁶; the remainder d⁷/5040 < 2e-18).
#[inline(always)]
fn exp_small(d: f64) -> f64 {
    1.0 + d
        * (1.0
            + d * (0.5
                + d * (1.0 / 6.0 + d * (1.0 / 24.0 + d * (1.0 / 120.0 + d * (1.0 / 720.0))))))
}

#[cfg(test)]
mod tests;
