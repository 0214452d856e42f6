//! Issue 11 acceptance, at CI size: `gtwatch demo` end to end (plant-sim over Modbus TCP on
//! 127.0.0.1 → the real daemon → SQLite → detector → diagnosis worker → trend and wash advice),
//! five plant days with the offline wash before day 3.
//!
//! Asserts against the implanted truth: every Method B parameter within 0.5 points; the wash is
//! detected before the right day's start-up; and the advised wash date, recomputed here from
//! the stored trend and the configured prices with the pure `trend`/`wash` functions, equals
//! the stored recommendation.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use gtwatch::config::Config;
use gtwatch::demo::{run_demo, DemoOptions};
use gtwatch::engine::Engine;
use gtwatch::health::HEALTH_NAMES;
use gtwatch::store::{HistoryFilter, Store};
use gtwatch::trend::{fit_rate, TrendPoint};
use gtwatch::wash::{advise, sensitivity, FoulingTrend};
use std::time::Duration;

const MS_PER_DAY: f64 = 86_400_000.0;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn demo_diagnoses_every_day_detects_the_wash_and_advises_reproducibly() {
    let dir = tempfile::tempdir().unwrap();
    let opts = DemoOptions {
        days: 5,
        seed: 3,
        out_dir: dir.path().join("demo"),
        timeout: Duration::from_secs(400),
        ..DemoOptions::default()
    };
    let report = run_demo(&opts, |_| {}).await.expect("demo runs");
    assert!(report.complete, "not every day was diagnosed: {report:#?}");
    assert_eq!(report.days.len(), 5, "{report:#?}");
    for d in &report.days {
        let b = d
            .method_b
            .as_ref()
            .unwrap_or_else(|| panic!("day {} not diagnosed: {d:?}", d.day));
        let truth = d.truth.to_array();
        for (i, n) in HEALTH_NAMES.iter().enumerate() {
            let est = b.health[*n];
            assert!(
                (est - truth[i]).abs() < 0.5,
                "day {}: {n} = {est:.3}, truth {:.3}",
                d.day,
                truth[i]
            );
        }
    }
    // The wash: detected (not recorded by anyone) before day 3's start-up, and only that one.
    assert_eq!(report.wash_day, Some(2));
    let detected: Vec<_> = report.washes.iter().filter(|w| w.detected).collect();
    assert_eq!(detected.len(), 1, "{:#?}", report.washes);
    assert_eq!(detected[0].before_day, Some(2), "{:#?}", report.washes);

    // The report: one page, nothing fetched from anywhere, with the trend, the wash and the advice.
    let html = std::fs::read_to_string(&report.report_path).unwrap();
    for bad in [
        "http:", "https:", "src=", "href=", "@import", "url(", "<script", "<img", "<link",
    ] {
        assert!(
            !html.contains(bad),
            "report has an external reference: '{bad}'"
        );
    }
    for title in [
        "D_GC compressor flow capacity",
        "D_EP power-turbine efficiency",
        "wash (detected)",
        "Latest diagnosed start-up",
        "residual, RMS",
    ] {
        assert!(html.contains(title), "report lacks '{title}'");
    }
    assert!(
        html.matches("<svg").count() >= 6 + 2 * 8,
        "six parameter charts and 8 trace/residual pairs"
    );

    // Recompute the advice from what is stored, independently of `advice::refresh`.
    let cfg = Config::load(&report.config_path).unwrap();
    // The configuration the demo leaves behind is complete: `check-config` accepts it.
    assert_eq!(cfg.check(), vec![], "demo config {:?}", report.config_path);
    let store = Store::open_readonly(&report.db_path).unwrap();
    let stored = store
        .latest_recommendation()
        .unwrap()
        .expect("a recommendation");
    let basis: serde_json::Value = serde_json::from_str(&stored.basis).unwrap();
    let last_wash = store
        .washes()
        .unwrap()
        .iter()
        .map(|w| w.t_ms)
        .max()
        .unwrap();
    let rows: Vec<_> = store
        .history(&HistoryFilter {
            method: Some("B".into()),
            ..HistoryFilter::default()
        })
        .unwrap()
        .into_iter()
        .filter(|r| r.start_ms > last_wash)
        .collect();
    assert_eq!(rows.len(), 3, "three start-ups after the wash");
    let fit = |p: &str| {
        let pts: Vec<TrendPoint> = rows
            .iter()
            .map(|r| TrendPoint {
                t_days: (r.start_ms - last_wash) as f64 / MS_PER_DAY,
                value: r.health[p],
                sigma: r.sigma[p],
            })
            .collect();
        fit_rate(&pts).unwrap()
    };
    let (gc, ec) = (fit("D_GC"), fit("D_EC"));
    let age = (rows.last().unwrap().start_ms - last_wash) as f64 / MS_PER_DAY;
    let trend = FoulingTrend {
        age_days: age,
        d_gc_now: gc.value_at(age),
        d_ec_now: ec.value_at(age),
        d_gc_rate: gc.rate_per_day,
        d_gc_rate_sigma: gc.rate_sigma_per_day,
        d_ec_rate: ec.rate_per_day,
        d_ec_rate_sigma: ec.rate_sigma_per_day,
    };
    let engine = Engine::reference().unwrap();
    let adv = advise(&trend, &sensitivity(&engine).unwrap(), &cfg.wash);
    let want = adv.advised_days.expect("advised days");
    let got = basis["advice"]["advised_days"]
        .as_f64()
        .expect("stored advised_days");
    assert!(
        (want - got).abs() < 1e-9,
        "recomputed {want} days, stored {got}: {}",
        stored.message
    );
    // Fouling after the wash grows: the advised wash is in the future of the last result.
    assert!(want > age, "advised {want} days, trend is {age} days old");
}
