use super::*;
use causal_arm_kinematics::{IkOptions, IkTarget};

/// Steps `sim` `steps` times with one command; returns the last state.
pub(crate) fn hold(sim: &mut Simulator, q: [f64; ARM_DOF], magnet: i8, steps: usize) -> SimState {
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

/// A world holding the lifted cube (the magnet on), and the joint targets that hold it there.
fn holding_lifted_cube() -> (Simulator, [f64; 7]) {
    let mut sim = Simulator::new(SimConfig {
        seed: 5,
        ..SimConfig::default()
    })
    .unwrap();
    let home = sim.config().home;
    let c = hold(&mut sim, home, 0, 20).cube_pose.translation.vector;
    let model = sim.model().clone();
    let down = |z: f64, initial: Option<Vec<f64>>| -> [f64; 7] {
        model
            .inverse(
                &IkTarget::pointing_down(c.x, c.y, z),
                &IkOptions {
                    initial,
                    ..IkOptions::default()
                },
            )
            .unwrap()
            .joints
            .try_into()
            .unwrap()
    };
    let above = down(c.z + 0.15, None);
    let touch = down(c.z + 0.03, Some(above.to_vec()));
    hold(&mut sim, above, 0, 80);
    hold(&mut sim, touch, 1, 40);
    let lifted = hold(&mut sim, above, 0, 60);
    assert!(lifted.holding && lifted.cube_pose.translation.z > c.z + 0.1);
    (sim, above)
}

/// Steps `sim` through `commands`, returning every state.
fn run(sim: &mut Simulator, commands: &[Command]) -> Vec<SimState> {
    commands.iter().map(|c| sim.step(c).unwrap()).collect()
}

/// Commands that move every joint and switch the magnet, so a snapshot is tested while
/// the arm, the servos' velocities and the cube are all in motion.
fn busy_commands(from: [f64; 7], n: usize) -> Vec<Command> {
    (0..n)
        .map(|k| Command {
            joint_targets: std::array::from_fn(|j| from[j] + 0.3 * ((k + j) as f64 * 0.7).sin()),
            magnet: [0, 0, -1, 0, 1, 0][k % 6],
        })
        .collect()
}

#[test]
fn a_snapshot_steps_bit_for_bit_as_the_original() {
    let (mut sim, above) = holding_lifted_cube();
    let commands = busy_commands(above, 40);
    let snapshot = sim.clone();
    let original = run(&mut sim, &commands);
    let replayed = run(&mut snapshot.clone(), &commands);
    let replayed_again = run(&mut snapshot.clone(), &commands);
    assert_eq!(original, replayed, "a snapshot diverged from the original");
    assert_eq!(
        replayed, replayed_again,
        "two replays of one snapshot differ"
    );
    // The run did move the cube and switch the magnet, so the check had something to check.
    assert!(original.iter().any(|s| !s.holding) && original.iter().any(|s| s.magnet_on));
}

#[test]
fn intervening_on_one_joint_command_changes_only_that_joint_and_the_tip() {
    let mut sim = Simulator::new(SimConfig {
        seed: 2,
        ..SimConfig::default()
    })
    .unwrap();
    let home = sim.config().home;
    hold(&mut sim, home, 0, 5);
    let command = Command {
        joint_targets: std::array::from_fn(|j| home[j] + 0.02 * j as f64),
        magnet: 0,
    };
    let mut edited = command.clone();
    edited.joint_targets[0] += 0.05;
    let factual = sim.clone().step(&command).unwrap();
    let counterfactual = sim.clone().step(&edited).unwrap();
    assert_ne!(
        factual.joint_positions[0], counterfactual.joint_positions[0],
        "theta0 must change"
    );
    for j in 1..7 {
        assert_eq!(
            factual.joint_positions[j].to_bits(),
            counterfactual.joint_positions[j].to_bits(),
            "theta{j} must be bit-identical"
        );
    }
    let moved =
        (factual.ef_pose.translation.vector - counterfactual.ef_pose.translation.vector).norm();
    assert!(moved > 1e-4, "ef moved {moved} m");
    assert_eq!(
        factual.cube_rgb, counterfactual.cube_rgb,
        "colour never changes"
    );
}

#[test]
fn switching_the_magnet_off_while_holding_drops_the_cube_within_a_few_steps() {
    let (sim, above) = holding_lifted_cube();
    let keep = Command {
        joint_targets: above,
        magnet: 0,
    };
    let off = Command {
        magnet: -1,
        ..keep.clone()
    };
    let factual = run(&mut sim.clone(), &vec![keep.clone(); 5]);
    let mut dropped = vec![off];
    dropped.extend(vec![keep; 4]);
    let counterfactual = run(&mut sim.clone(), &dropped);
    let fall = factual[4].cube_pose.translation.z - counterfactual[4].cube_pose.translation.z;
    assert!(factual[4].holding && !counterfactual[4].holding);
    assert!(
        fall > 0.02,
        "the released cube fell only {fall} m in 5 steps"
    );
    // The arm did the same in both worlds, and the colour never changed.
    assert_eq!(
        factual[4].joint_positions,
        counterfactual[4].joint_positions
    );
    assert_eq!(factual[4].cube_rgb, counterfactual[4].cube_rgb);
}
