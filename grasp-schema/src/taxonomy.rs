//! The grasp taxonomy of the paper's Table 1: grasp types, the hand pre-shapes
//! they map to, the thumb configuration of each pre-shape, and the classifier's
//! output classes (the four pre-shapes plus `no_grasp`).
//!
//! Names and class indices are part of the on-disk format (datasets,
//! checkpoints, the Hannes protocol): never reorder or rename them.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// A grasp type from Feix et al.'s taxonomy, as used in Table 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum GraspType {
    #[serde(rename = "adducted_thumb")]
    AdductedThumb,
    #[serde(rename = "large_diameter")]
    LargeDiameter,
    #[serde(rename = "small_diameter")]
    SmallDiameter,
    #[serde(rename = "medium_wrap")]
    MediumWrap,
    #[serde(rename = "sphere_4fingers")]
    Sphere4Fingers,
    #[serde(rename = "power_sphere")]
    PowerSphere,
    #[serde(rename = "prismatic_4fingers")]
    Prismatic4Fingers,
    #[serde(rename = "tripod")]
    Tripod,
    #[serde(rename = "prismatic_2fingers")]
    Prismatic2Fingers,
}

impl GraspType {
    /// Every grasp type, in Table 1's column order.
    pub const ALL: [GraspType; 9] = [
        GraspType::AdductedThumb,
        GraspType::LargeDiameter,
        GraspType::SmallDiameter,
        GraspType::MediumWrap,
        GraspType::Sphere4Fingers,
        GraspType::PowerSphere,
        GraspType::Prismatic4Fingers,
        GraspType::Tripod,
        GraspType::Prismatic2Fingers,
    ];

    /// The stable snake_case name used in files.
    pub fn name(self) -> &'static str {
        match self {
            GraspType::AdductedThumb => "adducted_thumb",
            GraspType::LargeDiameter => "large_diameter",
            GraspType::SmallDiameter => "small_diameter",
            GraspType::MediumWrap => "medium_wrap",
            GraspType::Sphere4Fingers => "sphere_4fingers",
            GraspType::PowerSphere => "power_sphere",
            GraspType::Prismatic4Fingers => "prismatic_4fingers",
            GraspType::Tripod => "tripod",
            GraspType::Prismatic2Fingers => "prismatic_2fingers",
        }
    }

    /// The pre-shape the prosthesis uses for this grasp type (Table 1).
    pub fn preshape(self) -> Preshape {
        match self {
            GraspType::AdductedThumb => Preshape::Lateral,
            GraspType::LargeDiameter
            | GraspType::SmallDiameter
            | GraspType::MediumWrap
            | GraspType::Sphere4Fingers
            | GraspType::PowerSphere => Preshape::Power,
            GraspType::Prismatic4Fingers => Preshape::Pinch,
            GraspType::Tripod | GraspType::Prismatic2Fingers => Preshape::Pinch3,
        }
    }
}

impl fmt::Display for GraspType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Error for a name that is not part of the taxonomy.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown {kind} '{name}' (expected one of: {expected})")]
pub struct UnknownName {
    pub kind: &'static str,
    pub name: String,
    pub expected: String,
}

impl FromStr for GraspType {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        GraspType::ALL
            .into_iter()
            .find(|g| g.name() == s)
            .ok_or_else(|| UnknownName {
                kind: "grasp type",
                name: s.to_string(),
                expected: GraspType::ALL.map(|g| g.name()).join(", "),
            })
    }
}

/// Thumb position that defines a pre-shape on the Hannes hand.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Thumb {
    Adducted,
    Central,
    Abducted,
}

/// A hand configuration: thumb position and whether the three-digit mode
/// (ring and little finger held open) is on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct HandConfiguration {
    pub thumb: Thumb,
    pub three_digit: bool,
}

/// A hand pre-shape of the Hannes prosthesis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Preshape {
    Power,
    Lateral,
    Pinch,
    /// "Pinch 3 Digit" in the paper.
    #[serde(rename = "pinch3")]
    Pinch3,
}

impl Preshape {
    pub const ALL: [Preshape; 4] = [
        Preshape::Power,
        Preshape::Lateral,
        Preshape::Pinch,
        Preshape::Pinch3,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Preshape::Power => "power",
            Preshape::Lateral => "lateral",
            Preshape::Pinch => "pinch",
            Preshape::Pinch3 => "pinch3",
        }
    }

    /// The paper's display name.
    pub fn paper_name(self) -> &'static str {
        match self {
            Preshape::Power => "Power",
            Preshape::Lateral => "Lateral",
            Preshape::Pinch => "Pinch",
            Preshape::Pinch3 => "Pinch 3 Digit",
        }
    }

    /// Table 1's "Definition" row: the thumb pose, plus the three-digit mode.
    pub fn hand_configuration(self) -> HandConfiguration {
        let (thumb, three_digit) = match self {
            Preshape::Lateral => (Thumb::Adducted, false),
            Preshape::Power => (Thumb::Central, false),
            Preshape::Pinch => (Thumb::Abducted, false),
            Preshape::Pinch3 => (Thumb::Abducted, true),
        };
        HandConfiguration { thumb, three_digit }
    }

    /// Inverse of [`Preshape::hand_configuration`]: the pre-shape a hand
    /// in configuration `c` is in, None for a configuration no pre-shape
    /// has (the host reads this from every acknowledgement).
    pub fn of_configuration(c: HandConfiguration) -> Option<Preshape> {
        Preshape::ALL
            .into_iter()
            .find(|p| p.hand_configuration() == c)
    }

    /// Folder name in the authors' dataset layout.
    pub fn authors_folder(self) -> &'static str {
        match self {
            Preshape::Power => "power_no3",
            Preshape::Lateral => "lateral_no3",
            Preshape::Pinch => "pinch_no3",
            Preshape::Pinch3 => "pinch_3",
        }
    }

    /// Inverse of [`Preshape::authors_folder`].
    pub fn from_authors_folder(folder: &str) -> Option<Preshape> {
        Preshape::ALL
            .into_iter()
            .find(|p| p.authors_folder() == folder)
    }

    /// The grasp types that map to this pre-shape.
    pub fn grasp_types(self) -> Vec<GraspType> {
        GraspType::ALL
            .into_iter()
            .filter(|g| g.preshape() == self)
            .collect()
    }
}

impl fmt::Display for Preshape {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Preshape {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Preshape::ALL
            .into_iter()
            .find(|p| p.name() == s || p.authors_folder() == s)
            .ok_or_else(|| UnknownName {
                kind: "pre-shape",
                name: s.to_string(),
                expected: Preshape::ALL.map(|p| p.name()).join(", "),
            })
    }
}

/// A classifier output class: one of the pre-shapes, or `no_grasp`.
///
/// Class indices are stable: power 0, lateral 1, pinch 2, pinch3 3, no_grasp 4.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Class {
    Power,
    Lateral,
    Pinch,
    #[serde(rename = "pinch3")]
    Pinch3,
    NoGrasp,
}

impl Class {
    pub const COUNT: usize = 5;
    pub const ALL: [Class; Class::COUNT] = [
        Class::Power,
        Class::Lateral,
        Class::Pinch,
        Class::Pinch3,
        Class::NoGrasp,
    ];

    pub fn index(self) -> usize {
        self as usize
    }

    pub fn from_index(index: usize) -> Option<Class> {
        Class::ALL.get(index).copied()
    }

    pub fn name(self) -> &'static str {
        match self {
            Class::NoGrasp => "no_grasp",
            other => other.preshape().map(Preshape::name).unwrap_or("no_grasp"),
        }
    }

    /// The pre-shape of this class, `None` for `no_grasp`.
    pub fn preshape(self) -> Option<Preshape> {
        match self {
            Class::Power => Some(Preshape::Power),
            Class::Lateral => Some(Preshape::Lateral),
            Class::Pinch => Some(Preshape::Pinch),
            Class::Pinch3 => Some(Preshape::Pinch3),
            Class::NoGrasp => None,
        }
    }

    /// Class names in index order, as written into checkpoints and reports.
    pub fn names() -> Vec<&'static str> {
        Class::ALL.iter().map(|c| c.name()).collect()
    }
}

impl From<Preshape> for Class {
    fn from(p: Preshape) -> Class {
        match p {
            Preshape::Power => Class::Power,
            Preshape::Lateral => Class::Lateral,
            Preshape::Pinch => Class::Pinch,
            Preshape::Pinch3 => Class::Pinch3,
        }
    }
}

impl fmt::Display for Class {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Class {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s == "no_grasp" {
            return Ok(Class::NoGrasp);
        }
        s.parse::<Preshape>()
            .map(Class::from)
            .map_err(|_| UnknownName {
                kind: "class",
                name: s.to_string(),
                expected: Class::names().join(", "),
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_configuration_names_its_preshape_or_none() {
        for p in Preshape::ALL {
            assert_eq!(Preshape::of_configuration(p.hand_configuration()), Some(p));
        }
        // Three digits with the thumb central or adducted is no pre-shape.
        for thumb in [Thumb::Central, Thumb::Adducted] {
            let c = HandConfiguration {
                thumb,
                three_digit: true,
            };
            assert_eq!(Preshape::of_configuration(c), None);
        }
    }

    #[test]
    fn table1_preshape_mapping() {
        use GraspType::*;
        let lateral = Preshape::Lateral.grasp_types();
        assert_eq!(lateral, vec![AdductedThumb]);
        assert_eq!(
            Preshape::Power.grasp_types(),
            vec![
                LargeDiameter,
                SmallDiameter,
                MediumWrap,
                Sphere4Fingers,
                PowerSphere
            ]
        );
        assert_eq!(Preshape::Pinch.grasp_types(), vec![Prismatic4Fingers]);
        assert_eq!(
            Preshape::Pinch3.grasp_types(),
            vec![Tripod, Prismatic2Fingers]
        );
    }

    #[test]
    fn thumb_definitions_follow_table1() {
        let cfg = |p: Preshape| p.hand_configuration();
        assert_eq!(cfg(Preshape::Lateral).thumb, Thumb::Adducted);
        assert_eq!(cfg(Preshape::Power).thumb, Thumb::Central);
        assert_eq!(cfg(Preshape::Pinch).thumb, Thumb::Abducted);
        assert_eq!(cfg(Preshape::Pinch3).thumb, Thumb::Abducted);
        assert!(cfg(Preshape::Pinch3).three_digit);
        assert!(!cfg(Preshape::Pinch).three_digit);
    }

    #[test]
    fn names_round_trip_through_serde_and_from_str() {
        for g in GraspType::ALL {
            let json = serde_json::to_string(&g).unwrap();
            assert_eq!(json, format!("\"{}\"", g.name()));
            assert_eq!(serde_json::from_str::<GraspType>(&json).unwrap(), g);
            assert_eq!(g.name().parse::<GraspType>().unwrap(), g);
        }
        for c in Class::ALL {
            let json = serde_json::to_string(&c).unwrap();
            assert_eq!(json, format!("\"{}\"", c.name()));
            assert_eq!(c.name().parse::<Class>().unwrap(), c);
            assert_eq!(Class::from_index(c.index()), Some(c));
        }
        for p in Preshape::ALL {
            assert_eq!(Preshape::from_authors_folder(p.authors_folder()), Some(p));
            assert_eq!(p.authors_folder().parse::<Preshape>().unwrap(), p);
        }
    }

    #[test]
    fn class_indices_are_stable() {
        assert_eq!(
            Class::names(),
            vec!["power", "lateral", "pinch", "pinch3", "no_grasp"]
        );
    }

    #[test]
    fn unknown_names_are_rejected_with_the_options() {
        let err = "power_disk".parse::<GraspType>().unwrap_err();
        assert!(err.to_string().contains("power_disk"));
        assert!(err.to_string().contains("adducted_thumb"));
        assert!("fist".parse::<Class>().is_err());
    }
}
