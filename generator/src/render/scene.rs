//! The static room and table geometry the Blender scene is built from. It
//! comes from the planner's scene config, so what is planned (collisions,
//! start points above the table) and what is drawn agree.

use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Room {
    /// Floor rectangle corners (x, y), metres; the floor is at z = 0.
    pub min_xy: [f64; 2],
    pub max_xy: [f64; 2],
    /// Ceiling height, metres.
    pub height: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Table {
    /// Table-top rectangle corners (x, y), metres.
    pub min_xy: [f64; 2],
    pub max_xy: [f64; 2],
    /// Height of the top surface, metres.
    pub height: f64,
    pub thickness: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneGeometry {
    pub room: Room,
    pub table: Table,
}

impl Default for SceneGeometry {
    /// A 4 x 5 m room with a 1.2 x 0.8 m table, 0.75 m high, at the centre.
    fn default() -> Self {
        SceneGeometry {
            room: Room {
                min_xy: [-2.0, -2.5],
                max_xy: [2.0, 2.5],
                height: 2.7,
            },
            table: Table {
                min_xy: [-0.6, -0.4],
                max_xy: [0.6, 0.4],
                height: 0.75,
                thickness: 0.04,
            },
        }
    }
}
