//! Procedural meshes of the built-in objects, sized from the real YCB
//! objects. Every kind builds its mesh from closed shells (`shapes`), then
//! moves it into the object frame (bottom centre of the bounding box at the
//! origin). Long objects lie along X.

mod containers;
mod elongated;
mod tools;
mod vessels;

use super::mesh::TriMesh;
use super::shapes::ellipsoid;
use containers::{bottle, can, tin};
use elongated::{banana, marker};
use serde::{Deserialize, Serialize};
use tools::{hammer, scissors, spatula, spoon};
use vessels::{mug, pitcher, plate};

/// Parameters of a built-in procedural shape (metres).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ProceduralShape {
    /// An axis-aligned box with slightly rounded vertical edges.
    Block { size: [f64; 3] },
    /// A cylinder standing on Z with a lip at the top (chips can).
    Can { radius: f64, height: f64, lip: f64 },
    /// A rounded-rectangle tin standing on Z (meat can).
    Tin { size: [f64; 3], corner: f64 },
    /// An ellipsoid resting on its lowest point (plum, baseball).
    Ellipsoid { size: [f64; 3] },
    /// A squeeze bottle with an elliptic body, a shoulder and a cap.
    Bottle {
        body: [f64; 3],
        cap_radius: f64,
        cap_height: f64,
    },
    /// A hollow cylinder with a bottom and a C-shaped handle on +X.
    Mug {
        radius: f64,
        height: f64,
        wall: f64,
        handle_reach: f64,
    },
    /// A hollow jug with a handle on +X and a spout on -X.
    Pitcher {
        radius: f64,
        height: f64,
        wall: f64,
        handle_reach: f64,
    },
    /// A plate with a raised rim.
    Plate { radius: f64, height: f64 },
    /// A curved tapered tube with a stem, bent towards +Y, along X.
    Banana { length: f64, bend: f64, radius: f64 },
    /// A handle along +X and a head (striking face and claw) across Y at -X.
    Hammer {
        length: f64,
        head_width: f64,
        thickness: f64,
    },
    /// Closed scissors: blades towards -X, two finger loops at +X.
    Scissors {
        length: f64,
        width: f64,
        thickness: f64,
    },
    /// A handle towards -X and a blade tilted up towards +X.
    Spatula {
        length: f64,
        blade_width: f64,
        height: f64,
    },
    /// A handle towards -X rising to its end and a bowl at +X.
    Spoon {
        length: f64,
        bowl_width: f64,
        height: f64,
    },
    /// A marker lying along X: a barrel, a cap at +X and a tapered end.
    Marker { length: f64, radius: f64 },
}

impl ProceduralShape {
    pub fn kind(&self) -> &'static str {
        match self {
            ProceduralShape::Block { .. } => "block",
            ProceduralShape::Can { .. } => "can",
            ProceduralShape::Tin { .. } => "tin",
            ProceduralShape::Ellipsoid { .. } => "ellipsoid",
            ProceduralShape::Bottle { .. } => "bottle",
            ProceduralShape::Mug { .. } => "mug",
            ProceduralShape::Pitcher { .. } => "pitcher",
            ProceduralShape::Plate { .. } => "plate",
            ProceduralShape::Banana { .. } => "banana",
            ProceduralShape::Hammer { .. } => "hammer",
            ProceduralShape::Scissors { .. } => "scissors",
            ProceduralShape::Spatula { .. } => "spatula",
            ProceduralShape::Spoon { .. } => "spoon",
            ProceduralShape::Marker { .. } => "marker",
        }
    }

    /// Every numeric parameter, with its name, for validation.
    pub fn parameters(&self) -> Vec<(&'static str, f64)> {
        use ProceduralShape::*;
        let v3 = |n: &'static str, s: &[f64; 3]| vec![(n, s[0]), (n, s[1]), (n, s[2])];
        match self {
            Block { size } | Ellipsoid { size } => v3("size", size),
            Can {
                radius,
                height,
                lip,
            } => vec![("radius", *radius), ("height", *height), ("lip", *lip)],
            Tin { size, corner } => [v3("size", size), vec![("corner", *corner)]].concat(),
            Bottle {
                body,
                cap_radius,
                cap_height,
            } => [
                v3("body", body),
                vec![("cap_radius", *cap_radius), ("cap_height", *cap_height)],
            ]
            .concat(),
            Mug {
                radius,
                height,
                wall,
                handle_reach,
            }
            | Pitcher {
                radius,
                height,
                wall,
                handle_reach,
            } => vec![
                ("radius", *radius),
                ("height", *height),
                ("wall", *wall),
                ("handle_reach", *handle_reach),
            ],
            Plate { radius, height } => vec![("radius", *radius), ("height", *height)],
            Banana {
                length,
                bend,
                radius,
            } => vec![("length", *length), ("bend", *bend), ("radius", *radius)],
            Hammer {
                length,
                head_width,
                thickness,
            } => vec![
                ("length", *length),
                ("head_width", *head_width),
                ("thickness", *thickness),
            ],
            Scissors {
                length,
                width,
                thickness,
            } => vec![
                ("length", *length),
                ("width", *width),
                ("thickness", *thickness),
            ],
            Spatula {
                length,
                blade_width,
                height,
            } => vec![
                ("length", *length),
                ("blade_width", *blade_width),
                ("height", *height),
            ],
            Spoon {
                length,
                bowl_width,
                height,
            } => vec![
                ("length", *length),
                ("bowl_width", *bowl_width),
                ("height", *height),
            ],
            Marker { length, radius } => vec![("length", *length), ("radius", *radius)],
        }
    }

    /// The mesh in the object frame.
    pub fn mesh(&self) -> TriMesh {
        use ProceduralShape::*;
        let m = match *self {
            Block { size } => tin(size, size[0].min(size[1]) * 0.04),
            Can {
                radius,
                height,
                lip,
            } => can(radius, height, lip),
            Tin { size, corner } => tin(size, corner),
            Ellipsoid { size } => ellipsoid([size[0] / 2.0, size[1] / 2.0, size[2] / 2.0], 32),
            Bottle {
                body,
                cap_radius,
                cap_height,
            } => bottle(body, cap_radius, cap_height),
            Mug {
                radius,
                height,
                wall,
                handle_reach,
            } => mug(radius, height, wall, handle_reach),
            Pitcher {
                radius,
                height,
                wall,
                handle_reach,
            } => pitcher(radius, height, wall, handle_reach),
            Plate { radius, height } => plate(radius, height),
            Banana {
                length,
                bend,
                radius,
            } => banana(length, bend, radius),
            Hammer {
                length,
                head_width,
                thickness,
            } => hammer(length, head_width, thickness),
            Scissors {
                length,
                width,
                thickness,
            } => scissors(length, width, thickness),
            Spatula {
                length,
                blade_width,
                height,
            } => spatula(length, blade_width, height),
            Spoon {
                length,
                bowl_width,
                height,
            } => spoon(length, bowl_width, height),
            Marker { length, radius } => marker(length, radius),
        };
        m.recentred()
    }
}
