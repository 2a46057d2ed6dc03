//! The babbler's design: how each component of an action was drawn given the state and
//! the action's other components. Motor babbling is a randomized experiment only where an
//! action is drawn at random; the design says where, and from what, so a test can resample
//! a component exactly and leave the scripted steps (IK while reaching, the release) out of
//! the evidence. It travels with every action (`Action.design`, msg/Draw.msg).

use causal_arm_msgs::msg::Draw as DrawMsg;

/// Where a joint draw is kept: the babbler redraws the joints together until the tool lies
/// in it, up to `tries` times.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolRegion {
    /// Redraws at most; a step where every try failed holds the arm (and is scripted).
    pub tries: u32,
    /// Lowest tool height, m, world frame.
    pub min_tool_z: f64,
    /// `[cx, cy, hx, hy]`: the tool within |x − cx| ≤ hx and |y − cy| ≤ hy, if given.
    pub tool_area: Option<[f64; 4]>,
}

impl ToolRegion {
    /// Whether a tool position lies in the region.
    pub fn holds(&self, tool: [f64; 3]) -> bool {
        tool[2] >= self.min_tool_z
            && self.tool_area.is_none_or(|[cx, cy, hx, hy]| {
                (tool[0] - cx).abs() <= hx && (tool[1] - cy).abs() <= hy
            })
    }
}

/// How one component of an action was drawn.
#[derive(Debug, Clone, PartialEq)]
pub enum Draw {
    /// Set from the state by a script: no randomization, so no evidence.
    Scripted,
    /// `clamp(center + N(0, sigma²), lower, upper)`, kept only inside `region` (if any).
    Normal {
        /// Mean before clamping.
        center: f64,
        /// Standard deviation.
        sigma: f64,
        /// Clamped to at least this.
        lower: f64,
        /// Clamped to at most this.
        upper: f64,
        /// Where the joint vector must put the tool.
        region: Option<ToolRegion>,
    },
    /// `values[i]` with probability `probabilities[i]`.
    Categorical {
        /// The values.
        values: Vec<f64>,
        /// Their probabilities (summing to 1).
        probabilities: Vec<f64>,
    },
}

/// The draw of every component of one action: the joints in order, then the magnet
/// (experiment 2). Empty: not known.
pub type Design = Vec<Draw>;

/// A command and how it was drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct Drawn {
    /// The command.
    pub command: crate::Command,
    /// How each of its components was drawn.
    pub design: Design,
}

impl Drawn {
    /// A command set wholly by a script (a controller, IK): every component scripted.
    pub fn scripted(command: crate::Command, components: usize) -> Self {
        Self {
            command,
            design: vec![Draw::Scripted; components],
        }
    }
}

/// Family codes of msg/Draw.msg.
const SCRIPTED: u8 = DrawMsg::SCRIPTED;
const NORMAL: u8 = DrawMsg::NORMAL;
const CATEGORICAL: u8 = DrawMsg::CATEGORICAL;

impl From<&Draw> for DrawMsg {
    fn from(draw: &Draw) -> Self {
        let mut msg = DrawMsg {
            family: SCRIPTED,
            center: 0.0,
            scale: 0.0,
            lower: 0.0,
            upper: 0.0,
            values: Vec::new(),
            probabilities: Vec::new(),
            tries: 0,
            min_tool_z: 0.0,
            tool_area: Vec::new(),
        };
        match draw {
            Draw::Scripted => {}
            Draw::Normal {
                center,
                sigma,
                lower,
                upper,
                region,
            } => {
                (msg.family, msg.center, msg.scale) = (NORMAL, *center, *sigma);
                (msg.lower, msg.upper) = (*lower, *upper);
                if let Some(r) = region {
                    (msg.tries, msg.min_tool_z) = (r.tries, r.min_tool_z);
                    msg.tool_area = r.tool_area.map(Vec::from).unwrap_or_default();
                }
            }
            Draw::Categorical {
                values,
                probabilities,
            } => {
                msg.family = CATEGORICAL;
                msg.values = values.clone();
                msg.probabilities = probabilities.clone();
            }
        }
        msg
    }
}

impl TryFrom<&DrawMsg> for Draw {
    type Error = String;

    /// The draw a message describes, or what is wrong with it.
    fn try_from(msg: &DrawMsg) -> Result<Self, String> {
        match msg.family {
            SCRIPTED => Ok(Self::Scripted),
            NORMAL => normal_of(msg),
            CATEGORICAL => categorical_of(msg),
            other => Err(format!(
                "family {other} is none of SCRIPTED (0), NORMAL (1), CATEGORICAL (2)"
            )),
        }
    }
}

fn normal_of(msg: &DrawMsg) -> Result<Draw, String> {
    if !(msg.scale.is_finite() && msg.scale > 0.0) {
        return Err(format!(
            "a NORMAL draw's scale must be positive, got {}",
            msg.scale
        ));
    }
    if !(msg.center.is_finite() && msg.lower <= msg.upper) {
        return Err(format!(
            "a NORMAL draw needs a finite center and lower <= upper, got center {}, [{}, {}]",
            msg.center, msg.lower, msg.upper
        ));
    }
    let region = match msg.tries {
        0 => None,
        tries => Some(ToolRegion {
            tries,
            min_tool_z: msg.min_tool_z,
            tool_area: match msg.tool_area.as_slice() {
                [] => None,
                &[cx, cy, hx, hy] => Some([cx, cy, hx, hy]),
                other => {
                    return Err(format!(
                        "tool_area must be empty or [cx, cy, hx, hy], got {} numbers",
                        other.len()
                    ));
                }
            },
        }),
    };
    Ok(Draw::Normal {
        center: msg.center,
        sigma: msg.scale,
        lower: msg.lower,
        upper: msg.upper,
        region,
    })
}

fn categorical_of(msg: &DrawMsg) -> Result<Draw, String> {
    let total: f64 = msg.probabilities.iter().sum();
    let valid = msg.values.len() == msg.probabilities.len()
        && !msg.values.is_empty()
        && msg.probabilities.iter().all(|p| (0.0..=1.0).contains(p))
        && (total - 1.0).abs() < 1e-9;
    if !valid {
        return Err(format!(
            "a CATEGORICAL draw needs one probability in [0, 1] per value, summing to 1; got values {:?}, probabilities {:?}",
            msg.values, msg.probabilities
        ));
    }
    Ok(Draw::Categorical {
        values: msg.values.clone(),
        probabilities: msg.probabilities.clone(),
    })
}

/// The design an action message carries: `Ok(None)` when it carries none (a publisher
/// that does not say), else one draw per component, or what is wrong with it (naming the
/// component).
pub fn design_of(design: &[DrawMsg], components: usize) -> Result<Option<Design>, String> {
    if design.is_empty() {
        return Ok(None);
    }
    if design.len() != components {
        return Err(format!(
            "design has {} draws for an action of {components} components",
            design.len()
        ));
    }
    design
        .iter()
        .enumerate()
        .map(|(i, d)| Draw::try_from(d).map_err(|e| format!("design[{i}]: {e}")))
        .collect::<Result<Design, _>>()
        .map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn joint() -> Draw {
        Draw::Normal {
            center: 0.3,
            sigma: 0.15,
            lower: -2.9,
            upper: 2.9,
            region: Some(ToolRegion {
                tries: 20,
                min_tool_z: 0.68,
                tool_area: Some([0.6, 0.0, 0.15, 0.25]),
            }),
        }
    }

    fn magnet() -> Draw {
        Draw::Categorical {
            values: vec![0.0, 1.0],
            probabilities: vec![0.95, 0.05],
        }
    }

    #[test]
    fn every_family_survives_its_message() {
        for draw in [Draw::Scripted, joint(), magnet()] {
            assert_eq!(Draw::try_from(&DrawMsg::from(&draw)), Ok(draw));
        }
        let bare = Draw::Normal {
            center: 0.0,
            sigma: 0.35,
            lower: -1.0,
            upper: 1.0,
            region: None,
        };
        assert_eq!(Draw::try_from(&DrawMsg::from(&bare)), Ok(bare));
    }

    #[test]
    fn a_bad_draw_is_refused_naming_the_component() {
        let mut msgs: Vec<DrawMsg> = [joint(), magnet()].iter().map(DrawMsg::from).collect();
        assert_eq!(design_of(&[], 8), Ok(None));
        assert!(
            design_of(&msgs, 8)
                .unwrap_err()
                .contains("2 draws for an action of 8")
        );
        msgs[1].probabilities = vec![0.5, 0.6];
        let err = design_of(&msgs, 2).unwrap_err();
        assert!(err.starts_with("design[1]: a CATEGORICAL draw"), "{err}");
        msgs[1] = DrawMsg::from(&magnet());
        msgs[0].scale = 0.0;
        assert!(
            design_of(&msgs, 2)
                .unwrap_err()
                .contains("scale must be positive")
        );
        msgs[0] = DrawMsg::from(&joint());
        msgs[0].tool_area = vec![1.0];
        assert!(
            design_of(&msgs, 2)
                .unwrap_err()
                .contains("[cx, cy, hx, hy]")
        );
        msgs[0].family = 7;
        assert!(design_of(&msgs, 2).unwrap_err().contains("family 7"));
    }

    #[test]
    fn the_region_holds_inside_its_height_and_area() {
        let Draw::Normal {
            region: Some(region),
            ..
        } = joint()
        else {
            unreachable!()
        };
        assert!(region.holds([0.6, 0.1, 0.7]));
        assert!(!region.holds([0.6, 0.1, 0.6]), "too low");
        assert!(!region.holds([0.8, 0.1, 0.7]), "off the area");
    }
}
