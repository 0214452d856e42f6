//! Per-call cost of the hot physics: gas properties and map look-ups.
//! Run: `cargo bench --bench physics`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: a failure is the test failing

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use gtwatch::maps::{self, ScaledCompressor, ScaledTurbine};
use gtwatch::thermo::Gas;

fn thermo(c: &mut Criterion) {
    let g = Gas::products(0.025);
    let mut t = 300.0;
    let mut next_t = move || {
        t = if t > 2100.0 { 300.0 } else { t + 37.7 };
        t
    };
    c.bench_function("thermo/products(far)", |b| {
        b.iter(|| Gas::products(black_box(0.025)))
    });
    c.bench_function("thermo/cp", |b| b.iter(|| g.cp(black_box(next_t()))));
    c.bench_function("thermo/h", |b| b.iter(|| g.h(black_box(next_t()))));
    c.bench_function("thermo/phi", |b| b.iter(|| g.phi(black_box(next_t()))));
    let h = g.h(1400.0);
    c.bench_function("thermo/t_from_h", |b| b.iter(|| g.t_from_h(black_box(h))));
    let phi = g.phi(1400.0);
    c.bench_function("thermo/t_from_phi", |b| {
        b.iter(|| g.t_from_phi(black_box(phi)))
    });
    let air = Gas::air();
    c.bench_function("thermo/isentropic_t compression", |b| {
        b.iter(|| air.isentropic_t(black_box(288.15), black_box(24.1)))
    });
    c.bench_function("thermo/isentropic_t expansion", |b| {
        b.iter(|| g.isentropic_t(black_box(1500.0), black_box(0.22)))
    });
}

fn map_lookups(c: &mut Criterion) {
    let hpc = maps::hpc().expect("embedded hpc");
    let hpt = maps::hpt().expect("embedded hpt");
    c.bench_function("maps/compressor point", |b| {
        b.iter(|| hpc.point(black_box(0.913), black_box(0.37)))
    });
    c.bench_function("maps/compressor beta_for_pr", |b| {
        b.iter(|| hpc.beta_for_pr(black_box(0.913), black_box(12.0)))
    });
    c.bench_function("maps/compressor point sub-idle", |b| {
        b.iter(|| hpc.point(black_box(0.21), black_box(0.6)))
    });
    c.bench_function("maps/turbine point", |b| {
        b.iter(|| hpt.point(black_box(0.93), black_box(4.4)))
    });
    c.bench_function("maps/turbine point below PRmin", |b| {
        b.iter(|| hpt.point(black_box(0.4), black_box(1.6)))
    });
    let sc = ScaledCompressor::calibrate(hpc, 1.0, 0.5, 9500.0, 80.0, 24.1, 0.85);
    let st = ScaledTurbine::calibrate(hpt, 1.0, 5.0, 9500.0, 12.5, 4.4, 0.88);
    c.bench_function("maps/scaled compressor at_pr", |b| {
        b.iter(|| sc.at_pr(black_box(8700.0), black_box(15.0)))
    });
    c.bench_function("maps/scaled turbine at_pr", |b| {
        b.iter(|| st.at_pr(black_box(8700.0), black_box(3.9)))
    });
}

criterion_group!(benches, thermo, map_lookups);
criterion_main!(benches);
