use gtwatch::engine::Engine;
use gtwatch::health::HealthParams;
fn main() {
    let e = Engine::reference().unwrap();
    let m = e.model(&HealthParams::HEALTHY);
    for nc in [100.0, 242.0, 500.0, 1000.0, 1835.0] {
        for pr in [1.05, 1.33, 2.0, 4.8] {
            let op = m.pt.at_pr(nc, pr);
            print!("nc {nc:6.0} pr {pr:4.2}: wc {:7.2} eff {:.3} | ", op.wc_kg_s, op.eff);
        }
        println!();
    }
    for nc in [500.0, 2000.0, 4000.0, 6500.0, 9500.0] {
        for pr in [1.0, 1.1, 1.5, 3.0] {
            let op = m.comp.at_pr(nc, pr);
            print!("C nc {nc:5.0} pr {pr:3.1}: wc {:6.2} eff {:.3} b {:5.2} sm {:6.1} | ", op.wc_kg_s, op.eff, op.beta, op.surge_margin_pct);
        }
        println!();
    }
}
