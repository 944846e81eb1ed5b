//! Checkpoints of format 1 and 2, written before the input record: their
//! preprocessing was a field of its own and their crop and denoising lived
//! in the trainer's options (`train_config.reader`). This maps them onto an
//! [`InputSpec`] once, at load; nothing else reads those fields.

use crate::input::preprocess::Preprocess;
use crate::input::{Crop, InputSpec};
use serde::de::DeserializeOwned;
use serde::Deserialize;
use serde_json::{Map, Value};

/// The format that introduced `input`.
pub const INPUT_RECORD_VERSION: u32 = 3;

/// Moves a format 1-2 checkpoint's input fields into `input`, in place.
/// Errors name the field (`train_config.reader.crop_angle_deg`, ...).
pub fn upgrade(meta: &mut Value) -> Result<(), String> {
    let Some(obj) = meta.as_object_mut() else {
        return Err("not a JSON object".into());
    };
    let preprocess: Preprocess = match obj.remove("preprocessing") {
        Some(p) => serde_json::from_value(p).map_err(|e| format!("preprocessing: {e}"))?,
        None => return Err("missing field `preprocessing`".into()),
    };
    let reader = obj
        .get("train_config")
        .and_then(|c| c.get("reader"))
        .and_then(Value::as_object)
        .cloned()
        .unwrap_or_default();
    let fraction: Option<f64> = field(&reader, "center_crop")?;
    let angle: Option<f64> = field(&reader, "crop_angle_deg")?;
    let denoise: Option<bool> = field(&reader, "denoise")?;
    let crop =
        Crop::from_options(fraction, angle).map_err(|e| format!("train_config.reader: {e}"))?;
    let input = InputSpec {
        crop,
        denoise: denoise.unwrap_or(false),
        preprocess,
    };
    obj.insert(
        "input".into(),
        serde_json::to_value(input).map_err(|e| e.to_string())?,
    );
    Ok(())
}

/// `reader.NAME` as a `T`; absent or null is `None`.
fn field<T: DeserializeOwned>(
    reader: &Map<String, Value>,
    name: &str,
) -> Result<Option<T>, String> {
    match reader.get(name) {
        None | Some(Value::Null) => Ok(None),
        Some(v) => Option::<T>::deserialize(v)
            .map_err(|e| format!("train_config.reader.{name} is {v}: {e}")),
    }
}
