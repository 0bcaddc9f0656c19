//! The paper's robot for the Rust tests and `cargo bench` (users get robots from the Python
//! catalog, `robocal.robot(...)`).

use crate::kinematics::{Chain, Convention, JointKind};

/// HSR JR680, the paper's Table I (standard DH, deg / mm), with a tool point and a cable anchor.
pub fn hsr_jr680() -> (Chain, Vec<f64>) {
    let chain = Chain::new(vec![Convention::Dh; 6], vec![JointKind::Revolute; 6]).expect("a valid chain");
    let table: [(f64, f64, f64, f64); 6] = [
        (-90.0, 250.0, 653.5, 0.0),
        (0.0, 900.0, 0.0, -90.0),
        (90.0, -205.0, 0.0, 180.0),
        (-90.0, 0.0, 1030.2, 0.0),
        (90.0, 0.0, 0.0, 90.0),
        (0.0, 0.0, 200.6, 0.0),
    ];
    let mut p = vec![0.0; chain.layout().n_params()];
    for (j, (alpha, a, d, theta)) in table.iter().enumerate() {
        let (ia, ii, id, it, _) = chain.layout().joint(j);
        (p[ia], p[ii], p[id], p[it]) = (alpha.to_radians(), *a, *d, theta.to_radians());
    }
    let (tool, sensor) = (chain.layout().tool(), chain.layout().sensor());
    p[tool..tool + 3].copy_from_slice(&[20.0, -15.0, 60.0]);
    p[sensor..sensor + 5].copy_from_slice(&[1500.0, 300.0, -200.0, 950.0, 1.0]);
    (chain, p)
}
