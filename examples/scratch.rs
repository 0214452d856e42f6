use gtwatch::engine::{sequence, Engine, Scenario};
use gtwatch::health::HealthParams;
fn main() {
    let e = Engine::reference().unwrap();
    println!("design {:?}", e.design);
    let m = e.model(&HealthParams::HEALTHY);
    let sc = Scenario::startup(&e.cfg);
    let t0 = std::time::Instant::now();
    let (s, stats) = sequence::run_scenario(&e.cfg, &m, &sc).unwrap();
    println!(
        "wall {:?} stats {:?} samples {}",
        t0.elapsed(),
        stats,
        s.len()
    );
    let mut last = None;
    for x in &s {
        let st = &x.stations;
        if last != Some(x.phase) || (x.t_s as i64) % 20 == 0 {
            println!("{:6.0} {:15} n1 {:7.0} n2 {:6.0} P2 {:7.1} T3 {:6.0} T34 {:6.0} P34 {:6.1} wf {:.3} W {:.2} pw {:6.2} sm {:5.1}",
              x.t_s, x.phase.to_string(), st.n1_rpm, st.n2_rpm, st.p2_kpa, st.t3_k, st.t34_k, st.p34_kpa, st.fuel_kg_s, st.air_kg_s, st.power_mw, st.surge_margin_pct);
            last = Some(x.phase);
        }
    }
}
