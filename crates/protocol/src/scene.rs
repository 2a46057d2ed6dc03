//! Geometry of the experiment 2 scene: the table the cube lies on and the cube.
//!
//! The simulator builds its world from these numbers and the dataset's contexts ("cube on
//! the table") judge states by them; one definition keeps the two in step without the
//! dataset having to build the simulator.

/// Height of the table's top surface, m.
pub const TABLE_TOP_Z: f64 = 0.20;
/// Table top centre (x, y), m.
pub const TABLE_CENTER: [f64; 2] = [0.58, 0.0];
/// Half extents of the table top (x, y), m.
pub const TABLE_HALF_EXTENTS: [f64; 2] = [0.20, 0.30];
/// Thickness of the table top, m.
pub const TABLE_THICKNESS: f64 = 0.04;
/// Edge length of the cube, m.
pub const CUBE_SIZE: f64 = 0.05;
/// How far the cube's centre may be from its resting height and still count as resting on
/// the table, m (a settled cube sits within a millimetre; a held or falling one is farther).
pub const RESTING_TOLERANCE: f64 = 5e-3;

/// The table and cube of one world, so a state can be judged against the geometry it was
/// simulated with (the simulator's configuration may differ from the defaults).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scene {
    /// Height of the table's top surface, m.
    pub table_top_z: f64,
    /// Table top centre (x, y), m.
    pub table_center: [f64; 2],
    /// Half extents of the table top (x, y), m.
    pub table_half_extents: [f64; 2],
    /// Edge length of the cube, m.
    pub cube_size: f64,
}

impl Default for Scene {
    /// The scene of the experiments ([`TABLE_TOP_Z`], [`TABLE_CENTER`],
    /// [`TABLE_HALF_EXTENTS`], [`CUBE_SIZE`]).
    fn default() -> Self {
        Self {
            table_top_z: TABLE_TOP_Z,
            table_center: TABLE_CENTER,
            table_half_extents: TABLE_HALF_EXTENTS,
            cube_size: CUBE_SIZE,
        }
    }
}

impl Scene {
    /// Pose of the table top's centre in the world (the `table_top` frame).
    pub fn table_pose(&self) -> nalgebra::Isometry3<f64> {
        let [x, y] = self.table_center;
        nalgebra::Isometry3::translation(x, y, self.table_top_z - TABLE_THICKNESS / 2.0)
    }

    /// A cube centred at `cube` (x, y, z, m) rests on the table top: its centre is half an
    /// edge above the top (within [`RESTING_TOLERANCE`]) and over the table. Whether the
    /// magnet holds it is the caller's to check.
    pub fn cube_rests_on_table(&self, cube: [f64; 3]) -> bool {
        let [x, y, z] = cube;
        let resting_z = self.table_top_z + self.cube_size / 2.0;
        (z - resting_z).abs() < RESTING_TOLERANCE
            && (x - self.table_center[0]).abs() <= self.table_half_extents[0]
            && (y - self.table_center[1]).abs() <= self.table_half_extents[1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cube_rests_on_the_table_only_at_the_top_and_over_it() {
        let scene = Scene::default();
        // Half an edge above the 0.20 m top.
        assert!(scene.cube_rests_on_table([0.58, 0.0, 0.225]));
        assert!(scene.cube_rests_on_table([0.70, -0.25, 0.228]));
        // Lifted, sunk, on the floor.
        assert!(!scene.cube_rests_on_table([0.58, 0.0, 0.26]));
        assert!(!scene.cube_rests_on_table([0.58, 0.0, 0.219]));
        assert!(!scene.cube_rests_on_table([0.58, 0.0, 0.025]));
        // Right height, beside the table (x from 0.38 to 0.78, y from -0.30 to 0.30).
        assert!(!scene.cube_rests_on_table([0.80, 0.0, 0.225]));
        assert!(!scene.cube_rests_on_table([0.58, 0.31, 0.225]));
        // Another table height moves the resting height with it.
        let low = Scene {
            table_top_z: 0.10,
            ..scene
        };
        assert!(low.cube_rests_on_table([0.58, 0.0, 0.125]));
        assert!(!low.cube_rests_on_table([0.58, 0.0, 0.225]));
    }
}
