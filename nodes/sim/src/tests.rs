use super::*;
use causal_arm_kinematics::{IkOptions, IkTarget};

fn hold(sim: &mut Simulator, q: [f64; ARM_DOF], magnet: i8, steps: usize) -> SimState {
    let mut state = sim.state();
    for _ in 0..steps {
        state = sim
            .step(&Command {
                joint_targets: q,
                magnet,
            })
            .unwrap();
    }
    state
}

#[test]
fn joints_track_targets_within_velocity_limits() {
    let mut sim = Simulator::new(SimConfig::default()).unwrap();
    let start = sim.state().joint_positions;
    let target = [0.3, 0.7, -0.2, -1.0, 0.4, 1.0, 0.5];
    let s1 = sim
        .step(&Command {
            joint_targets: target,
            magnet: 0,
        })
        .unwrap();
    let step_time = 10.0 / 240.0;
    let limits = sim.model().limits().to_vec();
    for i in 0..ARM_DOF {
        let moved = (s1.joint_positions[i] - start[i]).abs();
        assert!(
            moved <= limits[i].velocity * step_time + 1e-9,
            "joint {i} moved {moved}"
        );
    }
    let s = hold(&mut sim, target, 0, 60);
    for i in 0..ARM_DOF {
        assert!(
            (s.joint_positions[i] - target[i]).abs() < 1e-6,
            "joint {i}: {:?}",
            s.joint_positions
        );
    }
    // ef pose is the FK of the joints.
    let fk = sim.model().ef_pose(&s.joint_positions).unwrap();
    assert!((fk.translation.vector - s.ef_pose.translation.vector).norm() < 1e-12);
    assert_eq!(s.stamp_ns, (61.0 * 10.0 / 240.0 * 1e9_f64).round() as u64);
}

#[test]
fn targets_beyond_limits_are_clamped() {
    let mut sim = Simulator::new(SimConfig::default()).unwrap();
    let s = hold(&mut sim, [0.0, 3.0, 0.0, 0.0, 0.0, 0.0, 0.0], 0, 100);
    assert!(
        (s.joint_positions[1] - 2.094).abs() < 1e-9,
        "{:?}",
        s.joint_positions
    );
    let err = sim
        .step(&Command {
            joint_targets: [f64::NAN; 7],
            magnet: 0,
        })
        .unwrap_err();
    assert!(err.to_string().contains("joint target 0 is NaN"), "{err}");
    let err = sim
        .step(&Command {
            joint_targets: [0.0; 7],
            magnet: 2,
        })
        .unwrap_err();
    assert!(
        err.to_string().contains("magnet must be -1, 0 or 1, got 2"),
        "{err}"
    );
}

#[test]
fn cube_rests_on_the_table() {
    let mut sim = Simulator::new(SimConfig {
        seed: 3,
        ..SimConfig::default()
    })
    .unwrap();
    let home = sim.config().home;
    let s = hold(&mut sim, home, 0, 50);
    let z = s.cube_pose.translation.z;
    assert!((z - 0.225).abs() < 2e-3, "cube z {z}");
}

#[test]
fn magnet_picks_lifts_and_drops_the_cube() {
    let mut sim = Simulator::new(SimConfig {
        seed: 5,
        ..SimConfig::default()
    })
    .unwrap();
    let home = sim.config().home;
    let rest = hold(&mut sim, home, 0, 20);
    let c = rest.cube_pose.translation.vector;
    let model = sim.model().clone();
    let above = model
        .inverse(
            &IkTarget::pointing_down(c.x, c.y, c.z + 0.15),
            &IkOptions::default(),
        )
        .unwrap()
        .joints;
    let touch = model
        .inverse(
            &IkTarget::pointing_down(c.x, c.y, c.z + 0.025 + 0.005),
            &IkOptions {
                initial: Some(above.clone()),
                ..IkOptions::default()
            },
        )
        .unwrap()
        .joints;
    let above: [f64; 7] = above.try_into().unwrap();
    let touch: [f64; 7] = touch.try_into().unwrap();
    hold(&mut sim, above, 0, 80);
    let s = hold(&mut sim, touch, 1, 40);
    assert!(
        s.magnet_on && s.holding,
        "magnet on {} holding {}",
        s.magnet_on,
        s.holding
    );
    let lifted = hold(&mut sim, above, 0, 60);
    assert!(lifted.holding);
    assert!(
        lifted.cube_pose.translation.z > c.z + 0.1,
        "cube z {}",
        lifted.cube_pose.translation.z
    );
    let released = sim
        .step(&Command {
            joint_targets: above,
            magnet: -1,
        })
        .unwrap();
    assert!(!released.magnet_on && !released.holding);
    let settled = hold(&mut sim, above, 0, 60);
    let z = settled.cube_pose.translation.z;
    assert!((z - 0.225).abs() < 5e-3, "cube settled at z {z}");
}

#[test]
fn episodes_randomise_cube_and_colour() {
    let mut sim = Simulator::new(SimConfig {
        seed: 9,
        ..SimConfig::default()
    })
    .unwrap();
    let a = sim.state();
    sim.reset_episode();
    let b = sim.state();
    assert_eq!(b.episode, 1);
    assert_ne!(a.cube_rgb, b.cube_rgb);
    assert!((a.cube_pose.translation.vector - b.cube_pose.translation.vector).norm() > 1e-3);
    // Same seed, same world.
    let again = Simulator::new(SimConfig {
        seed: 9,
        ..SimConfig::default()
    })
    .unwrap()
    .state();
    assert_eq!(again, a);
}

/// Shape kinds of every collider, to check which URDF cylinders became capsules.
fn shape_kinds(sim: &Simulator) -> (usize, usize) {
    let (mut capsules, mut cylinders) = (0, 0);
    for (_, collider) in sim.world.colliders.iter() {
        let shape = collider.shape();
        capsules += shape.as_capsule().is_some() as usize;
        cylinders += shape.as_cylinder().is_some() as usize;
    }
    (capsules, cylinders)
}

#[test]
fn link_cylinders_become_capsules_except_the_magnet() {
    let fast = Simulator::new(SimConfig::default()).unwrap();
    let exact = Simulator::new(SimConfig {
        link_cylinders: LinkCylinders::Exact,
        ..SimConfig::default()
    })
    .unwrap();
    let (fast_capsules, fast_cylinders) = shape_kinds(&fast);
    let (exact_capsules, exact_cylinders) = shape_kinds(&exact);
    assert_eq!(exact_capsules, 0);
    assert_eq!(fast_cylinders, 1, "only the magnet tool stays a cylinder");
    assert_eq!(fast_capsules + fast_cylinders, exact_cylinders);
}
