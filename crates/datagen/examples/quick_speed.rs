//! Rough steps/s of simulator + babbler in one process (the real benchmark is `causal-arm bench`).
use causal_arm_babbler::{Exp1Babbler, Exp1Config, Exp2Babbler, Exp2Config};
use causal_arm_kinematics::ArmModel;
use causal_arm_sim::{SimConfig, Simulator};

fn main() {
    let model = ArmModel::embedded();
    let n = 5000;
    let mut sim = Simulator::new(SimConfig::default()).unwrap();
    let mut b = Exp1Babbler::new(&model, &Exp1Config::default()).unwrap();
    let mut s = sim.state();
    let t = std::time::Instant::now();
    for _ in 0..n {
        s = sim.step(&b.next(&s)).unwrap();
    }
    println!("exp1: {:.0} steps/s", n as f64 / t.elapsed().as_secs_f64());
    let mut sim = Simulator::new(SimConfig::default()).unwrap();
    let mut b = Exp2Babbler::new(&model, Exp2Config::default()).unwrap();
    let mut s = sim.state();
    let t = std::time::Instant::now();
    for _ in 0..n {
        s = sim.step(&b.next(&s)).unwrap();
    }
    println!("exp2: {:.0} steps/s", n as f64 / t.elapsed().as_secs_f64());
}
