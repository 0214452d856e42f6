//! Gas properties of dry air and lean methane combustion products.
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
//! through the lower heating value of methane at 288.15 K (fuel supplied at 288.15 K, so its
//! sensible enthalpy is zero too):
//! `(W_air + W_fuel) · h_products(T3) = W_air · h_air(T2) + η_b · W_fuel · LHV`.
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

// Molar masses, kg/kmol, from Cantera's atomic weights.
const W_H: f64 = 1.008;
const W_C: f64 = 12.011;
const W_N: f64 = 14.007;
const W_O: f64 = 15.999;
const W_AR: f64 = 39.95;
const W_N2: f64 = 2.0 * W_N;
const W_O2: f64 = 2.0 * W_O;
const W_CO2: f64 = W_C + 2.0 * W_O;
const W_H2O: f64 = 2.0 * W_H + W_O;
const W_CH4: f64 = W_C + 4.0 * W_H;

/// NASA 7-coefficient polynomial pair (low range, high range) of one species, gri30.yaml.
struct Species {
    w: f64,
    lo: [f64; 7],
    hi: [f64; 7],
}

const N2: Species = Species {
    w: W_N2,
    lo: [
        3.298677,
        1.4082404e-03,
        -3.963222e-06,
        5.641515e-09,
        -2.444854e-12,
        -1020.8999,
        3.950372,
    ],
    hi: [
        2.92664,
        1.4879768e-03,
        -5.68476e-07,
        1.0097038e-10,
        -6.753351e-15,
        -922.7977,
        5.980528,
    ],
};
const O2: Species = Species {
    w: W_O2,
    lo: [
        3.78245636,
        -2.99673416e-03,
        9.84730201e-06,
        -9.68129509e-09,
        3.24372837e-12,
        -1063.94356,
        3.65767573,
    ],
    hi: [
        3.28253784,
        1.48308754e-03,
        -7.57966669e-07,
        2.09470555e-10,
        -2.16717794e-14,
        -1088.45772,
        5.45323129,
    ],
};
const AR: Species = Species {
    w: W_AR,
    lo: [2.5, 0.0, 0.0, 0.0, 0.0, -745.375, 4.366],
    hi: [2.5, 0.0, 0.0, 0.0, 0.0, -745.375, 4.366],
};
const CO2: Species = Species {
    w: W_CO2,
    lo: [
        2.35677352,
        8.98459677e-03,
        -7.12356269e-06,
        2.45919022e-09,
        -1.43699548e-13,
        -4.83719697e+04,
        9.90105222,
    ],
    hi: [
        3.85746029,
        4.41437026e-03,
        -2.21481404e-06,
        5.23490188e-10,
        -4.72084164e-14,
        -4.8759166e+04,
        2.27163806,
    ],
};
const H2O: Species = Species {
    w: W_H2O,
    lo: [
        4.19864056,
        -2.0364341e-03,
        6.52040211e-06,
        -5.48797062e-09,
        1.77197817e-12,
        -3.02937267e+04,
        -0.849032208,
    ],
    hi: [
        3.03399249,
        2.17691804e-03,
        -1.64072518e-07,
        -9.7041987e-11,
        1.68200992e-14,
        -3.00042971e+04,
        4.9667701,
    ],
};

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
    /// Dry air (`far` = 0).
    pub fn air() -> Gas {
        Gas { far: 0.0, c: AIR }
    }

    /// Products of complete lean combustion of methane in dry air at fuel-air ratio `far`
    /// (kg fuel / kg air), clamped to `0 ..= FAR_MAX`. `products(0.0)` equals `air()`.
    pub fn products(far: f64) -> Gas {
        let far = if far.is_nan() {
            0.0
        } else {
            far.clamp(0.0, FAR_MAX)
        };
        let inv = 1.0 / (1.0 + far);
        let (a, d) = (&AIR, &DELTA);
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
        for _ in 0..40 {
            let t = x.exp();
            let dx = (self.phi_ln(t, x) - target) / self.cp(t);
            x -= dx;
            // Error after a step is O(dx²): |dx| < 3e-6 leaves a relative T error < 1e-11.
            if dx.abs() <= 3e-6 {
                break;
            }
        }
        x.exp()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_constants_match() {
        assert_eq!(LN_T_REF, T_REF_K.ln());
        assert_eq!(LN_T_MID, T_MID.ln());
        assert_eq!(LN_T_EXT_LO, T_EXT_LO.ln());
        assert_eq!(LN_T_EXT_HI, T_EXT_HI.ln());
    }

    #[test]
    fn air_gas_constant_and_molar_mass() {
        assert!((M_AIR - 28.9657).abs() < 1e-3, "M_air = {M_AIR}");
        assert!((Gas::air().r() - 287.0448).abs() < 1e-3);
        assert_eq!(Gas::products(0.0), Gas::air());
    }

    #[test]
    fn stoichiometric_far_is_about_0_058() {
        // O2 in the products vanishes at stoichiometric: y_O2 + far * delta_O2 = 0.
        let far_st = -Y_AIR[1] / Y_DELTA[1];
        assert!((far_st - 0.0580).abs() < 5e-4, "far_st = {far_st}");
    }

    /// Every row of the Cantera reference file. Tolerances: cp, R, γ 0.2 % relative;
    /// h − h(288.15) 0.2 % relative with an absolute floor of 0.2 % of cp × 50 K (≈100 J/kg),
    /// because h → 0 near 288.15 K and a relative test is meaningless there; φ likewise
    /// (0.2 % with a floor of 0.2 % of cp × ln(338/288) ≈ 0.3 J/(kg K)).
    #[test]
    fn matches_cantera_reference_every_row() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shared/reference/gas_properties_cantera.csv"
        );
        let mut rdr = csv::Reader::from_path(path).expect("reference csv present");
        let mut rows = 0;
        let mut worst = [0.0f64; 5]; // cp rel, R rel, gamma rel, h rel-to-tol, phi rel-to-tol
        let mut worst_abs = [0.0f64; 2]; // h abs J/kg, phi abs J/(kg K)
        for rec in rdr.records() {
            let rec = rec.expect("csv row");
            let v: Vec<f64> = rec
                .iter()
                .map(|s| s.trim().parse::<f64>().expect("number"))
                .collect();
            let (far, t, cp, r, gamma, dh, ds) = (v[0], v[1], v[2], v[3], v[4], v[5], v[6]);
            let g = Gas::products(far);
            let e_cp = (g.cp(t) / cp - 1.0).abs();
            let e_r = (g.r() / r - 1.0).abs();
            let e_g = (g.gamma(t) / gamma - 1.0).abs();
            let h_tol = (2e-3 * dh.abs()).max(2e-3 * cp * 50.0);
            let e_h = (g.h(t) - dh).abs();
            let phi_tol = (2e-3 * ds.abs()).max(2e-3 * cp * (338.15f64 / 288.15).ln());
            let e_phi = (g.phi(t) - ds).abs();
            assert!(e_cp < 2e-3, "cp far {far} T {t}: {} vs {cp}", g.cp(t));
            assert!(e_r < 2e-3, "R far {far}: {} vs {r}", g.r());
            assert!(
                e_g < 2e-3,
                "gamma far {far} T {t}: {} vs {gamma}",
                g.gamma(t)
            );
            assert!(e_h < h_tol, "h far {far} T {t}: {} vs {dh}", g.h(t));
            assert!(e_phi < phi_tol, "phi far {far} T {t}: {} vs {ds}", g.phi(t));
            worst[0] = worst[0].max(e_cp);
            worst[1] = worst[1].max(e_r);
            worst[2] = worst[2].max(e_g);
            worst[3] = worst[3].max(e_h / h_tol);
            worst[4] = worst[4].max(e_phi / phi_tol);
            worst_abs[0] = worst_abs[0].max(e_h);
            worst_abs[1] = worst_abs[1].max(e_phi);
            rows += 1;
        }
        assert!(rows >= 300, "only {rows} rows read");
        eprintln!(
            "cantera check, {rows} rows: worst rel cp {:.2e}, R {:.2e}, gamma {:.2e}; \
             h {:.3} J/kg ({:.1e} of tol), phi {:.2e} J/kgK ({:.1e} of tol)",
            worst[0], worst[1], worst[2], worst_abs[0], worst[3], worst_abs[1], worst[4]
        );
    }

    #[test]
    fn zero_at_reference_for_every_far() {
        for i in 0..=68 {
            let g = Gas::products(i as f64 * 0.001);
            assert!(g.h(T_REF_K).abs() < 1e-8, "h(288.15) = {}", g.h(T_REF_K));
            assert!(g.phi(T_REF_K).abs() < 1e-11);
        }
    }

    #[test]
    fn continuous_at_range_switches() {
        for far in [0.0, 0.02, 0.04, 0.068] {
            let g = Gas::products(far);
            for tb in [T_EXT_LO, T_MID, T_EXT_HI] {
                let (a, b) = (tb * (1.0 - 1e-12), tb * (1.0 + 1e-12));
                assert!((g.h(a) - g.h(b)).abs() < 1e-4, "h jump at {tb}");
                assert!((g.phi(a) - g.phi(b)).abs() < 1e-7, "phi jump at {tb}");
                assert!((g.cp(a) - g.cp(b)).abs() < 1e-2, "cp jump at {tb}");
            }
        }
    }

    #[test]
    fn derivatives_are_consistent() {
        // dh/dT = cp and dφ/dT = cp/T, by central differences across the whole range.
        let g = Gas::products(0.03);
        let mut t = 160.0;
        while t < 2500.0 {
            let d = 1e-3;
            let dh = (g.h(t + d) - g.h(t - d)) / (2.0 * d);
            let dphi = (g.phi(t + d) - g.phi(t - d)) / (2.0 * d);
            assert!((dh / g.cp(t) - 1.0).abs() < 1e-6, "dh/dT at {t}");
            assert!((dphi * t / g.cp(t) - 1.0).abs() < 1e-5, "dphi/dT at {t}");
            t += 37.0;
        }
    }

    #[test]
    fn inverse_round_trips() {
        for far in [0.0, 0.01, 0.025, 0.04, 0.058, 0.068] {
            let g = Gas::products(far);
            let mut t = 150.0;
            while t <= 2500.0 {
                let th = g.t_from_h(g.h(t));
                let tp = g.t_from_phi(g.phi(t));
                assert!(
                    (th / t - 1.0).abs() < 1e-10,
                    "t_from_h far {far} T {t}: {th}"
                );
                assert!(
                    (tp / t - 1.0).abs() < 1e-10,
                    "t_from_phi far {far} T {t}: {tp}"
                );
                t += 7.3;
            }
        }
    }

    #[test]
    fn isentropic_consistency() {
        let air = Gas::air();
        // Compression of ISO air by 24.1: T2s ≈ 288.15 * 24.1^(0.2857..) ≈ 720 K with real cp.
        let t2 = air.isentropic_t(T_REF_K, 24.1);
        assert!((700.0..740.0).contains(&t2), "T2s = {t2}");
        let lhs = air.phi(t2) - air.phi(T_REF_K);
        assert!((lhs - air.r() * 24.1f64.ln()).abs() < 1e-9);
        // Expansion back recovers the inlet temperature.
        let back = air.isentropic_t(t2, 1.0 / 24.1);
        assert!((back / T_REF_K - 1.0).abs() < 1e-12);
        // Products, hot expansion: identity holds and temperature falls.
        let g = Gas::products(0.025);
        for (t_in, pr) in [
            (1500.0, 0.2),
            (1400.0, 1.0 / 6.0),
            (900.0, 0.5),
            (1200.0, 1.0),
        ] {
            let t_out = g.isentropic_t(t_in, pr);
            let d = g.phi(t_out) - g.phi(t_in) - g.r() * f64::ln(pr);
            assert!(d.abs() < 1e-9, "residual {d}");
            assert!(t_out <= t_in);
        }
        assert!((g.isentropic_t(1200.0, 1.0) / 1200.0 - 1.0).abs() < 1e-14);
    }

    #[test]
    fn products_clamp_far() {
        assert_eq!(Gas::products(-0.01), Gas::air());
        assert_eq!(Gas::products(0.1).far(), FAR_MAX);
        assert_eq!(Gas::products(f64::NAN), Gas::air());
    }
}
