//! The scene as `visualization_msgs/MarkerArray`, so a bag or a live graph draws in RViz,
//! Foxglove or Lichtblick without a plugin: the table, the cube in its colour and the
//! magnet's state at the tool tip. Each marker is frame-locked to its tf frame, so it
//! follows `/tf` as the arm and the cube move.

use causal_arm_msgs::builtin_interfaces::msg::Duration;
use causal_arm_msgs::geometry_msgs::msg::{Pose, Vector3};
use causal_arm_msgs::std_msgs::msg::{ColorRGBA, Header};
use causal_arm_msgs::visualization_msgs::msg::{Marker, MarkerArray};

use crate::messages::StepMessages;
use crate::scene::{Scene, TABLE_THICKNESS};
use crate::topics::frames;

/// Colour of the table top (that of `urdf/table.urdf`).
const TABLE_RGBA: [f32; 4] = [0.6, 0.45, 0.3, 1.0];
/// Diameter of the sphere that shows the magnet at the tool tip, m.
const MAGNET_DIAMETER: f64 = 0.03;

/// What the magnet marker shows: off, on with nothing held, or holding the cube.
fn magnet_look(on: bool, holding: bool) -> ([f32; 4], &'static str) {
    match (on, holding) {
        (_, true) => ([0.1, 0.8, 0.1, 1.0], "magnet: holding"),
        (true, false) => ([1.0, 0.6, 0.0, 1.0], "magnet: on"),
        (false, false) => ([0.5, 0.5, 0.5, 0.6], "magnet: off"),
    }
}

fn rgba([r, g, b, a]: [f32; 4]) -> ColorRGBA {
    ColorRGBA { r, g, b, a }
}

/// One frame-locked shape of `size` (m) centred on `frame`, kept until replaced.
fn marker(m: &StepMessages, frame: &str, ns: &str, kind: i32, size: [f64; 3]) -> Marker {
    let [x, y, z] = size;
    Marker {
        header: Header {
            stamp: m.clock.clock.clone(),
            frame_id: frame.to_owned(),
        },
        ns: ns.to_owned(),
        id: 0,
        r#type: kind,
        action: Marker::ADD,
        pose: Pose::default(),
        scale: Vector3 { x, y, z },
        lifetime: Duration::default(),
        frame_locked: true,
        ..Marker::default()
    }
}

/// The scene at the step of `m`: table, cube (its colour from `/object/color`) and magnet
/// (its colour and label from `/magnet/state`), drawn in the frames `/tf` and `/tf_static`
/// carry.
pub fn scene_markers(m: &StepMessages, scene: &Scene) -> MarkerArray {
    let [hx, hy] = scene.table_half_extents;
    let table = Marker {
        color: rgba(TABLE_RGBA),
        ..marker(
            m,
            frames::TABLE,
            "table",
            Marker::CUBE,
            [2.0 * hx, 2.0 * hy, TABLE_THICKNESS],
        )
    };
    let c = &m.object_color.color;
    let edge = scene.cube_size;
    let cube = Marker {
        color: rgba([c.r, c.g, c.b, 1.0]),
        ..marker(m, frames::OBJECT, "object", Marker::CUBE, [edge; 3])
    };
    let (colour, label) = magnet_look(m.magnet.on, m.magnet.holding);
    let magnet = Marker {
        color: rgba(colour),
        ..marker(
            m,
            frames::EF,
            "magnet",
            Marker::SPHERE,
            [MAGNET_DIAMETER; 3],
        )
    };
    let text = Marker {
        id: 1,
        color: rgba(colour),
        text: label.to_owned(),
        ..marker(
            m,
            frames::EF,
            "magnet",
            Marker::TEXT_VIEW_FACING,
            [0.0, 0.0, 0.04],
        )
    };
    MarkerArray {
        markers: vec![table, cube, magnet, text],
    }
}

/// What of a step the markers show: a new array is due when it changes.
pub fn markers_key(m: &StepMessages) -> ([u32; 3], bool, bool) {
    let c = &m.object_color.color;
    (
        [c.r.to_bits(), c.g.to_bits(), c.b.to_bits()],
        m.magnet.on,
        m.magnet.holding,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::messages::tests::state;
    use crate::step_messages;

    #[test]
    fn markers_show_the_cube_colour_and_the_magnet_state() {
        let mut s = state();
        s.magnet_on = true;
        s.holding = true;
        let m = step_messages(&s, &["j"; 7], Vec::new());
        let array = scene_markers(&m, &Scene::default());
        let frames: Vec<_> = array
            .markers
            .iter()
            .map(|k| k.header.frame_id.as_str())
            .collect();
        assert_eq!(
            frames,
            [frames::TABLE, frames::OBJECT, frames::EF, frames::EF]
        );
        assert!(
            array
                .markers
                .iter()
                .all(|k| k.frame_locked && k.header.stamp == m.clock.clock)
        );
        let cube = &array.markers[1];
        assert_eq!(
            (cube.color.r, cube.color.g, cube.color.b),
            (0.25, 0.5, 0.75)
        );
        assert_eq!(cube.scale.x, 0.05);
        assert_eq!(array.markers[0].scale.y, 0.6);
        assert_eq!(array.markers[3].text, "magnet: holding");
        // (ns, id) name each marker once, so a new array replaces the old one.
        let mut names: Vec<_> = array.markers.iter().map(|k| (k.ns.clone(), k.id)).collect();
        names.dedup();
        assert_eq!(names.len(), 4);
        s.holding = false;
        s.magnet_on = false;
        let off = step_messages(&s, &["j"; 7], Vec::new());
        assert_eq!(
            scene_markers(&off, &Scene::default()).markers[3].text,
            "magnet: off"
        );
        assert_ne!(markers_key(&m), markers_key(&off));
    }
}
