//! Wash advice: when the next offline compressor wash pays for itself.
//!
//! Pure arithmetic (the engine model is only asked for steady points): no I/O, no clock, no store.
//!
//! **Economic criterion.** Between washes the recoverable (compressor) degradation grows; at base
//! load the unit burns its base-load fuel and delivers less power, so it loses
//! `c(t) = price_power · ΔP(t)` per operating hour (the heat-rate penalty is the same loss seen per
//! kWh and is reported, not counted twice). A wash costs `W` = wash cost + downtime × base power ×
//! the unit's margin (power price − fuel cost per MWh). Washing every `T` operating hours costs
//! on average `A(T) = (W + ∫₀ᵀ c(t) dt) / T` per hour; the advised interval minimises `A`. For a
//! loss rate growing linearly, `c(t) = c₀ + a t`, this is the classic square-root interval
//! `T* = √(2W / a)` (c₀ does not change it); [`optimal_interval_h`] solves the general case
//! numerically and a test checks it against the closed form.
//!
//! **Threshold rule.** Independently of money, wash when D_EC or the power loss would pass a limit
//! (from the engine file's operating practice, in the config): whichever date comes first wins.
//!
//! The uncertainty of the date comes from the uncertainty of the fouling rate: `T* ∝ a^(−1/2)`, so
//! `σ_T / T = σ_a / (2a)`.

use crate::engine::{Demand, Engine, SteadyInputs};
use crate::health::HealthParams;
use serde::{Deserialize, Serialize};

/// The currency the prices are in: an ISO 4217 code (three capital letters), printed with every
/// cost the advice states (a plant's prices carry their unit as any other number does).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct Currency([u8; 3]);

impl Currency {
    /// The code, e.g. `EUR`.
    pub fn code(&self) -> &str {
        // Built only from three ASCII capitals (`TryFrom`), so always valid UTF-8.
        std::str::from_utf8(&self.0).unwrap_or("???")
    }
}

impl Default for Currency {
    fn default() -> Self {
        Currency(*b"EUR")
    }
}

impl TryFrom<String> for Currency {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        match s.as_bytes() {
            [a, b, c] if [a, b, c].iter().all(|x| x.is_ascii_uppercase()) => {
                Ok(Currency([*a, *b, *c]))
            }
            _ => Err(format!(
                "currency {s:?}: must be a three-letter ISO 4217 code such as EUR, USD or GBP"
            )),
        }
    }
}

impl From<Currency> for String {
    fn from(c: Currency) -> String {
        c.code().to_string()
    }
}

impl std::fmt::Display for Currency {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.code())
    }
}

/// Prices and limits, from the `[wash]` section of the daemon config.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WashEconomics {
    /// The currency of every price and cost below.
    pub currency: Currency,
    /// Electricity sold, currency per MWh.
    pub power_price_per_mwh: f64,
    /// Fuel bought, currency per GJ (LHV).
    pub fuel_price_per_gj: f64,
    /// Materials and labour of one offline wash, currency.
    pub offline_wash_cost: f64,
    /// Hours the unit is off line for an offline wash (cool-down, soak, dry, restart).
    pub offline_wash_downtime_h: f64,
    /// Operating hours per calendar day (to turn operating hours into a date).
    pub operating_hours_per_day: f64,
    /// Wash when D_EC is expected to pass this many percent.
    pub max_d_ec_pct: f64,
    /// Wash when the base-load power loss is expected to pass this percentage of base power.
    pub max_power_loss_pct: f64,
}

impl Default for WashEconomics {
    fn default() -> Self {
        WashEconomics {
            currency: Currency::default(),
            power_price_per_mwh: 80.0,
            fuel_price_per_gj: 8.0,
            offline_wash_cost: 15_000.0,
            offline_wash_downtime_h: 8.0,
            operating_hours_per_day: 24.0,
            max_d_ec_pct: 2.0,
            max_power_loss_pct: 5.0,
        }
    }
}

impl WashEconomics {
    /// Checks that every value is finite and in its range; names the key at fault.
    pub fn validate(&self) -> Result<(), String> {
        let checks: [(&str, f64, f64, f64); 7] = [
            ("power_price_per_mwh", self.power_price_per_mwh, 0.0, 1e5),
            ("fuel_price_per_gj", self.fuel_price_per_gj, 0.0, 1e4),
            ("offline_wash_cost", self.offline_wash_cost, 0.0, 1e9),
            (
                "offline_wash_downtime_h",
                self.offline_wash_downtime_h,
                0.0,
                1e4,
            ),
            (
                "operating_hours_per_day",
                self.operating_hours_per_day,
                0.01,
                24.0,
            ),
            ("max_d_ec_pct", self.max_d_ec_pct, 0.01, 50.0),
            ("max_power_loss_pct", self.max_power_loss_pct, 0.01, 100.0),
        ];
        for (key, v, lo, hi) in checks {
            if !v.is_finite() || v < lo || v > hi {
                return Err(format!("wash.{key} = {v}: must be within {lo} … {hi}"));
            }
        }
        Ok(())
    }
}

/// How the engine's base-load output responds to each health parameter (per percent point),
/// from the engine model at base-load fuel flow.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sensitivity {
    /// Base-load power of the healthy engine, MW.
    pub base_power_mw: f64,
    /// Base-load fuel flow, kg/s.
    pub base_fuel_kg_s: f64,
    /// Fuel lower heating value, MJ/kg.
    pub lhv_mj_kg: f64,
    /// Power lost per point of each health parameter (D_GC … D_EP order), MW.
    pub mw_per_point: [f64; 6],
}

impl Sensitivity {
    /// Power lost at `h`, MW (linear in the health parameters).
    pub fn power_loss_mw(&self, h: &HealthParams) -> f64 {
        h.to_array()
            .iter()
            .zip(self.mw_per_point)
            .map(|(d, s)| d * s)
            .sum()
    }

    /// Heat-rate increase at `h`, fraction (same fuel, less power).
    pub fn heat_rate_increase(&self, h: &HealthParams) -> f64 {
        let p = self.base_power_mw - self.power_loss_mw(h);
        if p <= 0.0 {
            f64::INFINITY
        } else {
            self.base_power_mw / p - 1.0
        }
    }

    /// The unit's margin per MWh: power price less the fuel it takes to make it.
    pub fn margin_per_mwh(&self, e: &WashEconomics) -> f64 {
        let heat_rate_gj_per_mwh = self.base_fuel_kg_s * self.lhv_mj_kg * 3.6 / self.base_power_mw;
        (e.power_price_per_mwh - e.fuel_price_per_gj * heat_rate_gj_per_mwh).max(0.0)
    }

    /// Total cost of one offline wash: materials and labour plus the margin lost while off line.
    pub fn wash_cost(&self, e: &WashEconomics) -> f64 {
        e.offline_wash_cost
            + e.offline_wash_downtime_h * self.base_power_mw * self.margin_per_mwh(e)
    }
}

/// Finite-difference step of the sensitivity, percent points.
const SENS_STEP: f64 = 1.0;

/// Computes the [`Sensitivity`] of `engine` at its base-load fuel flow on its reference day.
pub fn sensitivity(engine: &Engine) -> Result<Sensitivity, crate::engine::EngineError> {
    let cfg = engine.cfg();
    let inputs = |demand| SteadyInputs {
        t_amb_k: cfg.ambient.temperature_k,
        p_amb_kpa: cfg.ambient.pressure_kpa,
        n2_rpm: cfg.design.pt_speed_rpm,
        demand,
    };
    let healthy = engine.model(&HealthParams::HEALTHY);
    let base = crate::engine::steady::solve(
        &healthy,
        &inputs(Demand::PowerMw(cfg.design.power_mw)),
        None,
    )?;
    let mut mw_per_point = [0.0; 6];
    for (i, s) in mw_per_point.iter_mut().enumerate() {
        let mut a = [0.0; 6];
        a[i] = SENS_STEP;
        let model = engine.model(&HealthParams::from_array(a));
        let p = crate::engine::steady::solve(
            &model,
            &inputs(Demand::FuelKgS(base.fuel_kg_s)),
            Some(&base),
        )?;
        *s = (base.power_mw - p.power_mw) / SENS_STEP;
    }
    Ok(Sensitivity {
        base_power_mw: base.power_mw,
        base_fuel_kg_s: base.fuel_kg_s,
        lhv_mj_kg: engine.consts().fuel.lhv() / 1e6,
        mw_per_point,
    })
}

/// The operating-hour interval `T` minimising `(wash_cost + ∫₀ᵀ loss(t) dt) / T` for a loss rate
/// `loss(t)` (currency per operating hour at `t` hours after the wash), searched on
/// `(0, max_h]`. `None` when the loss never grows enough to pay for a wash within `max_h`.
pub fn optimal_interval_h(wash_cost: f64, loss: impl Fn(f64) -> f64, max_h: f64) -> Option<f64> {
    // Trapezoid-integrated cumulative loss on a log-spaced grid, then golden-section refinement
    // of the average cost around the best grid point.
    let avg = |t: f64| -> f64 {
        let n = 400;
        let h = t / n as f64;
        let mut s = 0.5 * (loss(0.0) + loss(t));
        for k in 1..n {
            s += loss(k as f64 * h);
        }
        (wash_cost + s * h) / t
    };
    let grid: Vec<f64> = (0..=200)
        .map(|k| max_h * 10f64.powf(-4.0 + 4.0 * k as f64 / 200.0))
        .collect();
    let (kbest, _) = grid
        .iter()
        .map(|&t| avg(t))
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    if kbest == grid.len() - 1 {
        return None; // still falling at the horizon: no finite optimum within it
    }
    let (mut a, mut b) = (
        grid[kbest.saturating_sub(1)],
        grid[(kbest + 1).min(grid.len() - 1)],
    );
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    for _ in 0..80 {
        if avg(c) < avg(d) {
            b = d;
        } else {
            a = c;
        }
        c = b - g * (b - a);
        d = a + g * (b - a);
    }
    Some(0.5 * (a + b))
}

/// The recoverable fouling trend since the last wash: rate and level of D_GC and D_EC.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FoulingTrend {
    /// Days since the last wash at which the trend is evaluated ("now").
    pub age_days: f64,
    pub d_gc_now: f64,
    pub d_ec_now: f64,
    /// Percent per day, with 1σ.
    pub d_gc_rate: f64,
    pub d_gc_rate_sigma: f64,
    pub d_ec_rate: f64,
    pub d_ec_rate_sigma: f64,
}

/// What the advice rests on and what it says.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WashAdvice {
    /// Operating hours after the last wash at which to wash, by the economic criterion.
    pub economic_interval_h: Option<f64>,
    /// ... its 1σ from the fouling rate's uncertainty.
    pub economic_interval_sigma_h: Option<f64>,
    /// Days after the last wash when D_EC or the power loss passes its limit.
    pub threshold_days: Option<f64>,
    /// Which rule decides: "economic", "threshold", or "none" (no fouling measured).
    pub decided_by: String,
    /// Days after the last wash advised for the next offline wash.
    pub advised_days: Option<f64>,
    /// Its 1σ, days.
    pub advised_sigma_days: Option<f64>,
    /// Growth of the hourly loss, currency per operating hour per operating hour.
    pub loss_growth_per_h2: f64,
    /// Loss per operating hour now, currency.
    pub loss_now_per_h: f64,
    /// Power lost now, MW, and heat-rate increase now, percent.
    pub power_loss_now_mw: f64,
    pub heat_rate_increase_now_pct: f64,
    /// Cost of one offline wash including lost margin, currency.
    pub wash_cost: f64,
    /// The currency of every cost here (the config's `wash.currency`).
    pub currency: Currency,
    /// The reasoning in plain words.
    pub summary: String,
}

/// Horizon of the economic search: five years of operation.
const MAX_INTERVAL_H: f64 = 5.0 * 8760.0;

/// Advises the next offline wash from the fouling trend (pure).
pub fn advise(trend: &FoulingTrend, sens: &Sensitivity, econ: &WashEconomics) -> WashAdvice {
    let hpd = econ.operating_hours_per_day;
    let comp = |gc: f64, ec: f64| HealthParams::from_array([gc, ec, 0.0, 0.0, 0.0, 0.0]);
    // Loss growth per operating hour from the compressor rates (per day → per hour).
    let mw_growth_per_day = sens.power_loss_mw(&comp(trend.d_gc_rate, trend.d_ec_rate));
    let mw_growth_sigma_per_day = ((sens.mw_per_point[0] * trend.d_gc_rate_sigma).powi(2)
        + (sens.mw_per_point[1] * trend.d_ec_rate_sigma).powi(2))
    .sqrt();
    let a = econ.power_price_per_mwh * mw_growth_per_day / hpd;
    let now_h = comp(trend.d_gc_now, trend.d_ec_now);
    let power_loss_now_mw = sens.power_loss_mw(&now_h);
    let loss_now = econ.power_price_per_mwh * power_loss_now_mw;
    let wash_cost = sens.wash_cost(econ);
    let (economic_interval_h, economic_interval_sigma_h) = if a > 0.0 {
        let t = optimal_interval_h(wash_cost, |t| a * t, MAX_INTERVAL_H);
        let rel = 0.5 * mw_growth_sigma_per_day / mw_growth_per_day;
        (t, t.map(|t| t * rel))
    } else {
        (None, None)
    };
    // Threshold rule: when D_EC or the power loss, extrapolated, passes its limit.
    let mut threshold_days: Option<f64> = None;
    let mut consider = |days: f64| {
        if days.is_finite() && days >= 0.0 {
            threshold_days = Some(threshold_days.map_or(days, |d: f64| d.min(days)));
        }
    };
    if trend.d_ec_rate > 0.0 {
        consider(trend.age_days + (econ.max_d_ec_pct - trend.d_ec_now).max(0.0) / trend.d_ec_rate);
    }
    if mw_growth_per_day > 0.0 {
        let limit_mw = econ.max_power_loss_pct / 100.0 * sens.base_power_mw;
        consider(trend.age_days + (limit_mw - power_loss_now_mw).max(0.0) / mw_growth_per_day);
    }
    let econ_days = economic_interval_h.map(|h| h / hpd);
    let (decided_by, advised_days, advised_sigma_days) = match (econ_days, threshold_days) {
        (Some(e), Some(t)) if t < e => ("threshold", Some(t), None),
        (Some(e), _) => (
            "economic",
            Some(e),
            economic_interval_sigma_h.map(|s| s / hpd),
        ),
        (None, Some(t)) => ("threshold", Some(t), None),
        (None, None) => ("none", None, None),
    };
    let summary = match advised_days {
        None => format!(
            "No compressor fouling is measurable since the last wash (D_GC {:+.3} ± {:.3} %/day): \
             no wash is due on economic or threshold grounds.",
            trend.d_gc_rate, trend.d_gc_rate_sigma
        ),
        Some(d) => {
            let when = if d <= trend.age_days {
                "now (the date has passed)".to_string()
            } else {
                format!("in {:.0} days", d - trend.age_days)
            };
            let sigma = advised_sigma_days
                .map(|s| format!(" (± {s:.1} days from the fouling rate's uncertainty)"))
                .unwrap_or_default();
            format!(
                "The compressor fouls at D_GC {:+.3} ± {:.3} and D_EC {:+.3} ± {:.3} percent points per \
                 day; {:.1} days into the trend (since the last wash, or the first result) it costs {:.2} MW ({:.2} % heat rate), {:.0} {cur} per \
                 operating hour. One offline wash costs {:.0} {cur} including the lost margin. \
                 Decided by the {} rule: wash {:.0} days after the last wash, {when}{sigma}.",
                trend.d_gc_rate,
                trend.d_gc_rate_sigma,
                trend.d_ec_rate,
                trend.d_ec_rate_sigma,
                trend.age_days,
                power_loss_now_mw,
                100.0 * sens.heat_rate_increase(&now_h),
                loss_now,
                wash_cost,
                decided_by,
                d,
                cur = econ.currency,
            )
        }
    };
    WashAdvice {
        economic_interval_h,
        economic_interval_sigma_h,
        threshold_days,
        decided_by: decided_by.into(),
        advised_days,
        advised_sigma_days,
        loss_growth_per_h2: a,
        loss_now_per_h: loss_now,
        power_loss_now_mw,
        heat_rate_increase_now_pct: 100.0 * sens.heat_rate_increase(&now_h),
        wash_cost,
        currency: econ.currency,
        summary,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_loss_gives_the_square_root_interval() {
        for (w, a) in [(20_000.0, 0.05), (1_000.0, 2.0), (50_000.0, 0.003)] {
            let t = optimal_interval_h(w, |t| 3.0 + a * t, MAX_INTERVAL_H).unwrap();
            let closed = (2.0 * w / a).sqrt();
            assert!(
                (t / closed - 1.0).abs() < 1e-4,
                "W {w} a {a}: {t} vs {closed}"
            );
        }
    }

    #[test]
    fn no_growth_means_no_economic_wash() {
        assert_eq!(optimal_interval_h(10_000.0, |_| 5.0, MAX_INTERVAL_H), None);
    }

    fn sens() -> Sensitivity {
        Sensitivity {
            base_power_mw: 31.4,
            base_fuel_kg_s: 1.585,
            lhv_mj_kg: 50.0,
            mw_per_point: [0.2, 0.6, 0.3, 0.5, 0.2, 0.4],
        }
    }

    #[test]
    fn advice_follows_the_closed_form_and_the_threshold() {
        let s = sens();
        let e = WashEconomics::default();
        let trend = FoulingTrend {
            age_days: 10.0,
            d_gc_now: 0.3,
            d_ec_now: 0.1,
            d_gc_rate: 0.03,
            d_gc_rate_sigma: 0.003,
            d_ec_rate: 0.01,
            d_ec_rate_sigma: 0.001,
        };
        let adv = advise(&trend, &s, &e);
        let a = e.power_price_per_mwh * (0.2 * 0.03 + 0.6 * 0.01) / 24.0;
        let closed_days = (2.0 * s.wash_cost(&e) / a).sqrt() / 24.0;
        assert_eq!(adv.decided_by, "economic");
        let d = adv.advised_days.unwrap();
        assert!((d / closed_days - 1.0).abs() < 1e-3, "{d} vs {closed_days}");
        // σ_T / T = σ_a / (2a), the two rates' errors (10 % each) adding in quadrature.
        let rel_a = (0.2f64 * 0.003).hypot(0.6 * 0.001) / (0.2 * 0.03 + 0.6 * 0.01);
        let sd = adv.advised_sigma_days.unwrap();
        assert!(
            (sd / d - 0.5 * rel_a).abs() < 1e-6,
            "{sd} vs {}",
            0.5 * rel_a * d
        );
        // Every cost is stated in the config's currency.
        let usd = WashEconomics {
            currency: Currency::try_from("USD".to_string()).unwrap(),
            ..e
        };
        let text = advise(&trend, &s, &usd).summary;
        assert!(
            text.contains("USD per operating hour") && text.contains("USD including"),
            "{text}"
        );
        // A tight D_EC limit takes over.
        let strict = WashEconomics {
            max_d_ec_pct: 0.2,
            ..e
        };
        let adv = advise(&trend, &s, &strict);
        assert_eq!(adv.decided_by, "threshold");
        assert!((adv.advised_days.unwrap() - 20.0).abs() < 1e-9);
        // No fouling: no advice.
        let clean = FoulingTrend {
            d_gc_rate: -0.001,
            d_ec_rate: -0.001,
            ..trend
        };
        assert_eq!(advise(&clean, &s, &e).decided_by, "none");
    }

    #[test]
    fn validate_names_the_key() {
        let bad = WashEconomics {
            offline_wash_cost: f64::NAN,
            ..WashEconomics::default()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .contains("wash.offline_wash_cost"));
        assert!(WashEconomics::default().validate().is_ok());
    }

    #[test]
    fn currency_is_an_iso_code_named_when_wrong() {
        let ok: WashEconomics = toml::from_str("currency = \"GBP\"").unwrap();
        assert_eq!(ok.currency.code(), "GBP");
        assert_eq!(WashEconomics::default().currency.code(), "EUR");
        for bad in ["usd", "EURO", "€", ""] {
            let err = toml::from_str::<WashEconomics>(&format!("currency = {bad:?}"))
                .unwrap_err()
                .to_string();
            assert!(err.contains("ISO 4217"), "{bad}: {err}");
        }
    }

    #[test]
    fn reference_engine_loses_power_when_fouled() {
        let engine = Engine::reference().unwrap();
        let s = sensitivity(&engine).unwrap();
        assert!((s.base_power_mw - 31.4).abs() < 0.2, "{s:?}");
        // Fouling (flow capacity and efficiency loss) costs power at fixed fuel.
        assert!(s.mw_per_point[0] > 0.0 && s.mw_per_point[1] > 0.0, "{s:?}");
        assert!(s.mw_per_point[1] < 3.0, "{s:?}");
    }
}
