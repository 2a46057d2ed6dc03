//! The babblers against the simulator: what each experiment's babbling does to the arm
//! and the cube. They live here, next to the step loop that joins the two, because the
//! babbler crate does not depend on the simulator.

use causal_arm_babbler::{Exp1Babbler, Exp1Config, Exp2Babbler, Exp2Config};
use causal_arm_kinematics::ArmModel;
use causal_arm_protocol::ARM_DOF;
use causal_arm_sim::{SimConfig, Simulator};

#[test]
fn exp1_targets_are_normal_within_limits() {
    let model = ArmModel::embedded();
    let mut sim = Simulator::new(SimConfig::default()).unwrap();
    let mut b = Exp1Babbler::new(
        &model,
        &Exp1Config {
            seed: 1,
            ..Default::default()
        },
    )
    .unwrap();
    let n = 20_000;
    let mut sum = [0.0; ARM_DOF];
    let mut sq = [0.0; ARM_DOF];
    let state = sim.state();
    for _ in 0..n {
        let c = b.next(&state);
        model.check_joints(&c.joint_targets).unwrap();
        for i in 0..ARM_DOF {
            sum[i] += c.joint_targets[i];
            sq[i] += c.joint_targets[i].powi(2);
        }
    }
    for i in 0..ARM_DOF {
        let mean = sum[i] / n as f64;
        let sd = (sq[i] / n as f64 - mean * mean).sqrt();
        assert!(
            mean.abs() < 0.01 && (sd - 0.35).abs() < 0.01,
            "joint {i}: mean {mean} sd {sd}"
        );
    }
    let _ = sim.step(&b.next(&state)).unwrap();
    assert!(
        Exp1Babbler::new(
            &model,
            &Exp1Config {
                sigma: -1.0,
                ..Default::default()
            }
        )
        .is_err()
    );
}

#[test]
fn exp2_picks_lifts_and_drops_the_cube() {
    let model = ArmModel::embedded();
    let mut sim = Simulator::new(SimConfig {
        seed: 11,
        ..SimConfig::default()
    })
    .unwrap();
    let mut b = Exp2Babbler::new(
        &model,
        Exp2Config {
            seed: 11,
            ..Default::default()
        },
    )
    .unwrap();
    let table_z = 0.225;
    let mut state = sim.state();
    let (mut picks, mut lifted_high, mut drops) = (0, false, 0u32);
    let mut was_holding = false;
    let (mut on_table, mut repicked, mut settle_in) = (0, 0, None::<u32>);
    let mut magnet_was_on = state.magnet_on;
    for _ in 0..2000 {
        let cmd = b.next(&state);
        // Every "off" command switches a magnet that is on (none is unobservable).
        if cmd.magnet == -1 {
            assert!(magnet_was_on, "off command while the magnet is already off");
        }
        state = sim.step(&cmd).unwrap();
        magnet_was_on = state.magnet_on;
        if state.holding && !was_holding {
            picks += 1;
        }
        if !state.holding && was_holding {
            drops += 1;
            settle_in = Some(30);
        }
        if let Some(n) = settle_in.as_mut() {
            *n -= 1;
            if *n == 0 {
                settle_in = None;
                // A dropped cube comes to rest on the table top, not the floor (unless
                // it has been picked up again).
                if state.holding {
                    repicked += 1;
                } else if (state.cube_pose.translation.z - table_z).abs() < 0.01 {
                    on_table += 1;
                }
            }
        }
        if state.holding && state.cube_pose.translation.z > table_z + 0.05 {
            lifted_high = true;
        }
        // The cube only leaves the table while held (or while falling right after a drop).
        if !state.holding && !was_holding {
            let z = state.cube_pose.translation.z;
            assert!(z < 1.0, "cube flew to {z}");
        }
        was_holding = state.holding;
    }
    assert!(picks >= 3, "only {picks} picks in 2000 steps");
    assert!(drops >= 2, "only {drops} drops");
    assert!(lifted_high, "cube never lifted");
    let settled = drops - repicked - u32::from(settle_in.is_some());
    assert!(
        on_table * 10 >= settled * 9,
        "only {on_table} of {settled} dropped cubes rest on the table"
    );
}

/// The design each exp 2 command carries says how it was drawn: the reaching, lifting
/// and placing are scripted; babbling and manoeuvres draw normal moves inside their region,
/// centred on the joints; the magnet is drawn while babbling and scripted elsewhere.
#[test]
fn exp2_designs_say_how_each_command_was_drawn() {
    use causal_arm_babbler::Phase;
    use causal_arm_protocol::Draw;

    let model = ArmModel::embedded();
    let mut sim = Simulator::new(SimConfig {
        seed: 5,
        ..SimConfig::default()
    })
    .unwrap();
    let config = Exp2Config {
        seed: 5,
        ..Default::default()
    };
    let mut b = Exp2Babbler::new(&model, config.clone()).unwrap();
    let mut state = sim.state();
    let (mut scripted_steps, mut random_steps, mut magnet_draws) = (0, 0, 0);
    let mut z = Vec::new();
    for _ in 0..3000 {
        let phase = b.phase().clone();
        let drawn = b.next_drawn(&state);
        let (command, design) = (&drawn.command, &drawn.design);
        assert_eq!(design.len(), ARM_DOF + 1);
        let q = state.joint_positions;
        let scripted_phase = matches!(
            phase,
            Phase::Approach { .. } | Phase::Descend { .. } | Phase::Place { .. }
        );
        match &design[ARM_DOF] {
            Draw::Categorical {
                values,
                probabilities,
            } => {
                magnet_draws += 1;
                assert!(
                    matches!(phase, Phase::Babble { min_remaining: 0 }),
                    "{phase:?}"
                );
                assert!(values.contains(&(command.magnet as f64)));
                assert!((probabilities.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            }
            Draw::Scripted => {}
            other => panic!("magnet drawn as {other:?}"),
        }
        match &design[0] {
            Draw::Scripted => scripted_steps += 1,
            Draw::Normal { .. } => {
                random_steps += 1;
                assert!(
                    !scripted_phase || command.magnet == -1,
                    "a random move while {phase:?}"
                );
                let tool = model.ef_pose(&command.joint_targets).unwrap().translation;
                for (i, draw) in design[..ARM_DOF].iter().enumerate() {
                    let Draw::Normal {
                        center,
                        sigma,
                        lower,
                        upper,
                        region,
                    } = draw
                    else {
                        panic!("joint {i} drawn otherwise than joint 0");
                    };
                    assert_eq!(*center, q[i], "a move is centred on the joints");
                    let target = command.joint_targets[i];
                    assert!((*lower..=*upper).contains(&target));
                    let region = region.as_ref().expect("a move keeps the tool safe");
                    assert!(region.holds([tool.x, tool.y, tool.z]), "{region:?}");
                    let expected = match (command.magnet, &phase) {
                        (-1, _) => config.babble_sigma / 3.0,
                        (_, Phase::Manoeuvre { .. }) => config.manoeuvre_sigma,
                        _ => config.babble_sigma,
                    };
                    assert!((sigma - expected).abs() < 1e-12, "{phase:?}: {sigma}");
                    if target > *lower && target < *upper {
                        z.push((target - center) / sigma);
                    }
                }
            }
            other => panic!("joint 0 drawn as {other:?}"),
        }
        if scripted_phase && command.magnet != -1 {
            assert!(matches!(design[0], Draw::Scripted), "{phase:?}");
        }
        state = sim.step(command).unwrap();
    }
    assert!(
        scripted_steps > 100 && random_steps > 1000,
        "{scripted_steps} {random_steps}"
    );
    assert!(magnet_draws > 100, "{magnet_draws}");
    // The kept moves are N(0, 1) in units of their spread (the region trims a little).
    let n = z.len() as f64;
    let mean = z.iter().sum::<f64>() / n;
    let sd = (z.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    assert!(
        mean.abs() < 0.05 && (0.85..1.05).contains(&sd),
        "mean {mean}, sd {sd}"
    );
}

#[test]
fn exp1_designs_are_the_papers_normal_about_the_mean() {
    use causal_arm_protocol::Draw;

    let model = ArmModel::embedded();
    let sim = Simulator::new(SimConfig::default()).unwrap();
    let config = Exp1Config {
        seed: 2,
        ..Default::default()
    };
    let mut b = Exp1Babbler::new(&model, &config).unwrap();
    let drawn = b.next_drawn(&sim.state());
    assert_eq!(drawn.design.len(), ARM_DOF);
    for (i, draw) in drawn.design.iter().enumerate() {
        let limits = &model.limits()[i];
        assert_eq!(
            draw,
            &Draw::Normal {
                center: 0.0,
                sigma: config.sigma,
                lower: limits.lower,
                upper: limits.upper,
                region: None
            }
        );
    }
    assert!(
        config
            .design_words()
            .contains(&format!("N(0, {}^2)", config.sigma))
    );
}
