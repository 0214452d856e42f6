//! Species data: atomic weights and NASA 7-coefficient polynomials.
//!
//! What it is for: the constants `thermo` builds its mixtures from. What it must not do:
//! anything but hold `const` data.
//!
//! Air and product species (N2, O2, Ar, CO2, H2O) and the fuel species CH4, C2H6, C3H8 and H2
//! are copied from Cantera's `gri30.yaml` (GRI-Mech 3.0 thermodynamics, Smith et al.,
//! http://combustion.berkeley.edu/gri-mech/). n-butane (C4H10) is not in GRI-Mech 3.0; its
//! polynomials are JetSurF 2.0's (`jetsurf.yaml`, entry noted `P11/94`, i.e. Burcat's
//! thermochemical database). The sixth coefficient carries each species' standard heat of
//! formation at 298.15 K, which is how [`super::fuel`] computes heating values.
//! C3H8 and C4H10 are fitted from 300 K; at the fuel temperatures used here (from 250 K) their
//! low-range polynomial is extrapolated by at most 50 K, as Cantera itself does.

// Molar masses, kg/kmol, from Cantera's atomic weights.
pub(super) const W_H: f64 = 1.008;
pub(super) const W_C: f64 = 12.011;
pub(super) const W_N: f64 = 14.007;
pub(super) const W_O: f64 = 15.999;
pub(super) const W_AR: f64 = 39.95;
pub(super) const W_N2: f64 = 2.0 * W_N;
pub(super) const W_O2: f64 = 2.0 * W_O;
pub(super) const W_CO2: f64 = W_C + 2.0 * W_O;
pub(super) const W_H2O: f64 = 2.0 * W_H + W_O;
pub(super) const W_CH4: f64 = W_C + 4.0 * W_H;

/// NASA 7-coefficient polynomial pair (low range, high range) of one species, gri30.yaml.
pub(super) struct Species {
    /// Molar mass, kg/kmol.
    pub(super) w: f64,
    /// Coefficients a1..a7 below 1000 K.
    pub(super) lo: [f64; 7],
    /// Coefficients a1..a7 above 1000 K.
    pub(super) hi: [f64; 7],
}

pub(super) const N2: Species = Species {
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
pub(super) const O2: Species = Species {
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
pub(super) const AR: Species = Species {
    w: W_AR,
    lo: [2.5, 0.0, 0.0, 0.0, 0.0, -745.375, 4.366],
    hi: [2.5, 0.0, 0.0, 0.0, 0.0, -745.375, 4.366],
};
pub(super) const CO2: Species = Species {
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
pub(super) const H2O: Species = Species {
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

pub(super) const W_C2H6: f64 = 2.0 * W_C + 6.0 * W_H;
pub(super) const W_C3H8: f64 = 3.0 * W_C + 8.0 * W_H;
pub(super) const W_C4H10: f64 = 4.0 * W_C + 10.0 * W_H;
pub(super) const W_H2: f64 = 2.0 * W_H;

pub(super) const CH4: Species = Species {
    w: W_CH4,
    lo: [
        5.14987613,
        -0.0136709788,
        4.91800599e-05,
        -4.84743026e-08,
        1.66693956e-11,
        -10246.6476,
        -4.64130376,
    ],
    hi: [
        0.074851495,
        0.0133909467,
        -5.73285809e-06,
        1.22292535e-09,
        -1.0181523e-13,
        -9468.34459,
        18.437318,
    ],
};
pub(super) const C2H6: Species = Species {
    w: W_C2H6,
    lo: [
        4.29142492,
        -0.0055015427,
        5.99438288e-05,
        -7.08466285e-08,
        2.68685771e-11,
        -11522.2055,
        2.66682316,
    ],
    hi: [
        1.0718815,
        0.0216852677,
        -1.00256067e-05,
        2.21412001e-09,
        -1.9000289e-13,
        -11426.3932,
        15.1156107,
    ],
};
pub(super) const C3H8: Species = Species {
    w: W_C3H8,
    lo: [
        0.93355381,
        0.026424579,
        6.1059727e-06,
        -2.1977499e-08,
        9.5149253e-12,
        -13958.52,
        19.201691,
    ],
    hi: [
        7.5341368,
        0.018872239,
        -6.2718491e-06,
        9.1475649e-10,
        -4.7838069e-14,
        -16467.516,
        -17.892349,
    ],
};
pub(super) const C4H10: Species = Species {
    w: W_C4H10,
    lo: [
        1.5685419,
        0.034652278,
        6.8168129e-06,
        -2.7995097e-08,
        1.2307742e-11,
        -17129.977,
        17.908045,
    ],
    hi: [
        10.526774,
        0.023590738,
        -7.852248e-06,
        1.1448408e-09,
        -5.9827703e-14,
        -20479.223,
        -32.198579,
    ],
};
pub(super) const H2: Species = Species {
    w: W_H2,
    lo: [
        2.34433112,
        0.00798052075,
        -1.9478151e-05,
        2.01572094e-08,
        -7.37611761e-12,
        -917.935173,
        0.683010238,
    ],
    hi: [
        3.3372792,
        -4.94024731e-05,
        4.99456778e-07,
        -1.79566394e-10,
        2.00255376e-14,
        -950.158922,
        -3.20502331,
    ],
};

impl Species {
    /// Molar enthalpy including the heat of formation, J/kmol, from the low-range polynomial
    /// (valid below 1000 K; used for fuels and reactants near room temperature).
    pub(super) fn h_molar_low(&self, t_k: f64) -> f64 {
        let a = &self.lo;
        super::R_UNIVERSAL
            * (t_k
                * (a[0]
                    + t_k
                        * (a[1] / 2.0
                            + t_k * (a[2] / 3.0 + t_k * (a[3] / 4.0 + t_k * a[4] / 5.0))))
                + a[5])
    }
}
