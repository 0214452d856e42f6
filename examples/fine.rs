use gtwatch::engine::{sequence::Simulation, Engine, Scenario};
use gtwatch::health::HealthParams;
fn main() {
    let e = Engine::reference().unwrap();
    let m = e.model(&HealthParams::HEALTHY);
    let sc = Scenario::startup(&e.cfg);
    let mut sim = Simulation::new(&e.cfg, &m, &sc);
    sim.advance_to(120.0).unwrap();
    for k in 0..40 {
        sim.advance_to(120.0 + k as f64 * 0.002).unwrap();
        let st = sim.stations();
        println!("{:.3} wf {:.6} far {:.6} T3 {:.3} P2 {:.4} n1 {:.3} I {:.6} sm {:.3}", sim.t, st.fuel_kg_s, sim.y[6]*0.02, st.t3_k, st.p2_kpa, st.n1_rpm, sim.y[5], st.surge_margin_pct);
    }
}
