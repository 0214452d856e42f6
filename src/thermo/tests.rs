//! Tests of the gas properties against Cantera and of their internal consistency.

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
        "/tests/data/reference/gas_properties_cantera.csv"
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

/// The short exponential series the entropy inverse steps with matches `exp` to within two
/// ulps wherever it is used (|d| < 1e-2).
#[test]
fn exp_series_matches_exp_where_used() {
    for k in -1000..=1000 {
        let d = k as f64 * 0.999e-5;
        let (a, b) = (super::exp_small(d), d.exp());
        assert!((a - b).abs() <= 2.0 * f64::EPSILON * b, "d {d}: {a} vs {b}");
    }
}
