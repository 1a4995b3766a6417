//! Parsing of the simulator's telemetry event: every value is a JSON string, numbers are .NET "N4"
//! text with either decimal separator, `position` is `x;y` and the sample lists are `;`-separated.

use base64::Engine as _;
use rover_msgs::unity::ReportedState;
use serde_json::{Map, Value};

/// One parsed telemetry frame, in the simulator's own units (degrees, Unity angle ranges).
#[derive(Debug, Clone, PartialEq)]
pub struct SimTelemetry {
    /// Controls and pose.
    pub state: ReportedState,
    /// A sample is within reach.
    pub near_sample: bool,
    /// The arm is picking up a sample.
    pub picking_up: bool,
    /// Samples still on the ground.
    pub sample_count: u32,
    /// Positions (x, y) of the samples still on the ground.
    pub samples: Vec<(f64, f64)>,
    /// The camera JPEG.
    pub image_jpeg: Vec<u8>,
}

/// Why a telemetry frame was rejected. The message names the field and what was expected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TelemetryError {
    /// The payload exceeds the size limit.
    #[error("telemetry payload of {bytes} bytes exceeds the limit of {limit} bytes")]
    TooLarge {
        /// Payload size.
        bytes: usize,
        /// Configured limit.
        limit: usize,
    },
    /// The payload is not valid JSON.
    #[error("telemetry payload is not valid JSON: {0}")]
    InvalidJson(String),
    /// The payload is JSON but not an object.
    #[error("telemetry payload is {0}, expected a JSON object")]
    NotAnObject(&'static str),
    /// A required field is absent.
    #[error("telemetry field `{0}` is missing")]
    MissingField(&'static str),
    /// A field is not a JSON string.
    #[error("telemetry field `{field}` is {found}, expected a string")]
    NotAString {
        /// Field name.
        field: &'static str,
        /// JSON kind found.
        found: &'static str,
    },
    /// A field's text is not a number.
    #[error("telemetry field `{field}` = {text:?} is not a number")]
    NotANumber {
        /// Field name.
        field: &'static str,
        /// The text.
        text: String,
    },
    /// A field's number is NaN or infinite.
    #[error("telemetry field `{field}` = {text:?} is not finite")]
    NotFinite {
        /// Field name.
        field: &'static str,
        /// The text.
        text: String,
    },
    /// `position` is not `x;y`.
    #[error("telemetry field `position` = {0:?} is not of the form \"x;y\"")]
    BadPosition(String),
    /// `samples_x` and `samples_y` have different lengths.
    #[error("telemetry fields `samples_x` ({x}) and `samples_y` ({y}) list different numbers of samples")]
    SampleListsDiffer {
        /// Entries in `samples_x`.
        x: usize,
        /// Entries in `samples_y`.
        y: usize,
    },
    /// A sample list is longer than [`MAX_SAMPLES`].
    #[error("telemetry field `{field}` lists {count} samples, more than the {MAX_SAMPLES} accepted")]
    TooManySamples {
        /// Field name.
        field: &'static str,
        /// Entries listed.
        count: usize,
    },
    /// `image` is not valid base64.
    #[error("telemetry field `image` is not valid base64: {0}")]
    BadBase64(String),
}

impl TelemetryError {
    /// A short stable name for counting rejections by kind in `/diagnostics`.
    pub fn kind(&self) -> &'static str {
        match self {
            TelemetryError::TooLarge { .. } => "too_large",
            TelemetryError::InvalidJson(_) => "invalid_json",
            TelemetryError::NotAnObject(_) => "not_an_object",
            TelemetryError::MissingField(_) => "missing_field",
            TelemetryError::NotAString { .. } => "not_a_string",
            TelemetryError::NotANumber { .. } => "not_a_number",
            TelemetryError::NotFinite { .. } => "not_finite",
            TelemetryError::BadPosition(_) => "bad_position",
            TelemetryError::SampleListsDiffer { .. } => "sample_lists_differ",
            TelemetryError::TooManySamples { .. } => "too_many_samples",
            TelemetryError::BadBase64(_) => "bad_base64",
        }
    }
}

/// Parses the JSON text of a `telemetry` event's argument. `Ok(None)` means an empty payload,
/// which the simulator's own client answers with `manual`.
pub fn parse_telemetry(payload: &str, max_bytes: usize) -> Result<Option<SimTelemetry>, TelemetryError> {
    check_size(payload.len(), max_bytes)?;
    let value: Value = serde_json::from_str(payload).map_err(|e| TelemetryError::InvalidJson(e.to_string()))?;
    parse_telemetry_value(&value)
}

/// Refuses a payload of `bytes` bytes when it is larger than `max_bytes`, before it is parsed.
pub fn check_size(bytes: usize, max_bytes: usize) -> Result<(), TelemetryError> {
    if bytes > max_bytes {
        return Err(TelemetryError::TooLarge { bytes, limit: max_bytes });
    }
    Ok(())
}

/// Like [`parse_telemetry`], on an already parsed argument (whose text passed [`check_size`]).
pub fn parse_telemetry_value(value: &Value) -> Result<Option<SimTelemetry>, TelemetryError> {
    let fields = match value {
        Value::Null => return Ok(None),
        Value::Object(fields) if fields.is_empty() => return Ok(None),
        Value::Object(fields) => fields,
        other => return Err(TelemetryError::NotAnObject(json_kind(other))),
    };
    parse_fields(fields).map(Some)
}

fn parse_fields(fields: &Map<String, Value>) -> Result<SimTelemetry, TelemetryError> {
    let number = |name| parse_number(name, text(fields, name)?);
    let (x_m, y_m) = parse_position(text(fields, "position")?)?;
    let samples_x = parse_list("samples_x", text(fields, "samples_x")?)?;
    let samples_y = parse_list("samples_y", text(fields, "samples_y")?)?;
    if samples_x.len() != samples_y.len() {
        return Err(TelemetryError::SampleListsDiffer { x: samples_x.len(), y: samples_y.len() });
    }
    let state = ReportedState {
        steering_angle_deg: number("steering_angle")?,
        throttle: number("throttle")?,
        brake: number("brake")?,
        speed_mps: number("speed")?,
        x_m,
        y_m,
        pitch_deg: number("pitch")?,
        yaw_deg: number("yaw")?,
        roll_deg: number("roll")?,
    };
    Ok(SimTelemetry {
        state,
        near_sample: number("near_sample")? != 0.0,
        picking_up: number("picking_up")? != 0.0,
        sample_count: number("sample_count")?.max(0.0) as u32,
        samples: samples_x.into_iter().zip(samples_y).collect(),
        image_jpeg: decode_image(text(fields, "image")?)?,
    })
}

fn text<'a>(fields: &'a Map<String, Value>, name: &'static str) -> Result<&'a str, TelemetryError> {
    match fields.get(name) {
        None => Err(TelemetryError::MissingField(name)),
        Some(Value::String(s)) => Ok(s),
        Some(other) => Err(TelemetryError::NotAString { field: name, found: json_kind(other) }),
    }
}

/// Parses a .NET "N4"-style number with `.` or `,` as the decimal separator and optional group separators.
pub fn parse_number(field: &'static str, text: &str) -> Result<f64, TelemetryError> {
    let normalized = normalize_decimal(text.trim());
    let value: f64 = normalized.parse().map_err(|_| TelemetryError::NotANumber { field, text: text.to_string() })?;
    if !value.is_finite() {
        return Err(TelemetryError::NotFinite { field, text: text.to_string() });
    }
    Ok(value)
}

/// Rewrites `1,234.5678` / `1.234,5678` / `0,5` to `1234.5678` / `1234.5678` / `0.5`.
fn normalize_decimal(text: &str) -> String {
    let last_dot = text.rfind('.');
    let last_comma = text.rfind(',');
    let decimal = match (last_dot, last_comma) {
        (Some(dot), Some(comma)) => Some(dot.max(comma)),
        (Some(at), None) | (None, Some(at)) => Some(at),
        (None, None) => None,
    };
    text.char_indices()
        .filter_map(|(at, c)| match c {
            '.' | ',' if Some(at) == decimal => Some('.'),
            '.' | ',' | '\u{a0}' | ' ' => None,
            other => Some(other),
        })
        .collect()
}

fn parse_position(text: &str) -> Result<(f64, f64), TelemetryError> {
    let (x, y) = text.split_once(';').ok_or_else(|| TelemetryError::BadPosition(text.to_string()))?;
    let x = parse_number("position", x).map_err(|_| TelemetryError::BadPosition(text.to_string()))?;
    let y = parse_number("position", y).map_err(|_| TelemetryError::BadPosition(text.to_string()))?;
    Ok((x, y))
}

/// Most samples a telemetry frame may list: Unity places six, and every one is republished.
pub const MAX_SAMPLES: usize = 64;

fn parse_list(field: &'static str, text: &str) -> Result<Vec<f64>, TelemetryError> {
    if text.trim().is_empty() {
        return Ok(Vec::new());
    }
    let count = text.split(';').count();
    if count > MAX_SAMPLES {
        return Err(TelemetryError::TooManySamples { field, count });
    }
    text.split(';').map(|item| parse_number(field, item)).collect()
}

fn decode_image(text: &str) -> Result<Vec<u8>, TelemetryError> {
    base64::engine::general_purpose::STANDARD.decode(text).map_err(|e| TelemetryError::BadBase64(e.to_string()))
}

fn json_kind(value: &Value) -> &'static str {
    match value {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn sample_payload() -> Map<String, Value> {
        let json = serde_json::json!({
            "steering_angle": "-4.3722", "throttle": "0.2000", "brake": "0.0000", "speed": "1.2345",
            "position": "99.6700;85.5890", "pitch": "359.5000", "yaw": "56.8255", "roll": "0.0000",
            "near_sample": "0", "picking_up": "1", "sample_count": "6",
            "samples_x": "97.44;122.28", "samples_y": "74.65;51.66", "image": "/9j/2Q==",
        });
        json.as_object().unwrap().clone()
    }

    fn parse(fields: &Map<String, Value>) -> Result<Option<SimTelemetry>, TelemetryError> {
        parse_telemetry(&serde_json::to_string(fields).unwrap(), 1 << 20)
    }

    #[test]
    fn parses_every_field() {
        let t = parse(&sample_payload()).unwrap().unwrap();
        assert_eq!(t.state.steering_angle_deg, -4.3722);
        assert_eq!((t.state.x_m, t.state.y_m), (99.67, 85.589));
        assert_eq!(t.state.pitch_deg, 359.5);
        assert!(!t.near_sample && t.picking_up);
        assert_eq!(t.sample_count, 6);
        assert_eq!(t.samples, vec![(97.44, 74.65), (122.28, 51.66)]);
        assert_eq!(t.image_jpeg, vec![0xFF, 0xD8, 0xFF, 0xD9]);
    }

    #[test]
    fn comma_decimals_and_group_separators() {
        assert_eq!(parse_number("speed", "0,5000").unwrap(), 0.5);
        assert_eq!(parse_number("speed", "-1,234.5678").unwrap(), -1234.5678);
        assert_eq!(parse_number("speed", "1.234,5678").unwrap(), 1234.5678);
        let mut fields = sample_payload();
        fields.insert("position".into(), "99,6700;85,5890".into());
        fields.insert("samples_x".into(), "97,44;122,28".into());
        let t = parse(&fields).unwrap().unwrap();
        assert_eq!((t.state.x_m, t.state.y_m), (99.67, 85.589));
        assert_eq!(t.samples[1].0, 122.28);
    }

    #[test]
    fn empty_payload_means_manual() {
        assert_eq!(parse_telemetry("{}", 100).unwrap(), None);
        assert_eq!(parse_telemetry("null", 100).unwrap(), None);
    }

    #[test]
    fn rejections_name_the_field() {
        let mut missing = sample_payload();
        missing.remove("yaw");
        assert_eq!(parse(&missing).unwrap_err(), TelemetryError::MissingField("yaw"));

        let mut number = sample_payload();
        number.insert("speed".into(), serde_json::json!(1.5));
        assert_eq!(parse(&number).unwrap_err(), TelemetryError::NotAString { field: "speed", found: "a number" });

        let mut text = sample_payload();
        text.insert("throttle".into(), "fast".into());
        assert_eq!(parse(&text).unwrap_err().kind(), "not_a_number");

        let mut nan = sample_payload();
        nan.insert("pitch".into(), "nan".into());
        assert_eq!(parse(&nan).unwrap_err(), TelemetryError::NotFinite { field: "pitch", text: "nan".into() });

        let mut position = sample_payload();
        position.insert("position".into(), "99.67".into());
        assert_eq!(parse(&position).unwrap_err().kind(), "bad_position");

        let mut lists = sample_payload();
        lists.insert("samples_y".into(), "1.0".into());
        assert_eq!(parse(&lists).unwrap_err(), TelemetryError::SampleListsDiffer { x: 2, y: 1 });

        let mut image = sample_payload();
        image.insert("image".into(), "not base64!".into());
        assert_eq!(parse(&image).unwrap_err().kind(), "bad_base64");

        assert_eq!(parse_telemetry("[1]", 100).unwrap_err(), TelemetryError::NotAnObject("an array"));
        assert_eq!(parse_telemetry("{", 100).unwrap_err().kind(), "invalid_json");
        assert_eq!(parse_telemetry("{}", 1).unwrap_err(), TelemetryError::TooLarge { bytes: 2, limit: 1 });
    }

    #[test]
    fn a_frame_listing_more_samples_than_accepted_is_refused() {
        let mut fields = sample_payload();
        let many = vec!["1.5"; MAX_SAMPLES + 1].join(";");
        fields.insert("samples_x".into(), many.clone().into());
        fields.insert("samples_y".into(), many.into());
        let error = parse(&fields).unwrap_err();
        assert_eq!(error.kind(), "too_many_samples");
        assert_eq!(error.to_string(), "telemetry field `samples_x` lists 65 samples, more than the 64 accepted");
    }

    #[test]
    fn empty_sample_lists_are_no_samples() {
        let mut fields = sample_payload();
        fields.insert("samples_x".into(), "".into());
        fields.insert("samples_y".into(), "".into());
        assert!(parse(&fields).unwrap().unwrap().samples.is_empty());
    }

    proptest::proptest! {
        #[test]
        fn n4_numbers_round_trip(value in -99_999.0f64..99_999.0, comma in proptest::prelude::any::<bool>()) {
            let text = format!("{value:.4}");
            let text = if comma { text.replace('.', ",") } else { text };
            let parsed = parse_number("speed", &text).unwrap();
            proptest::prop_assert!((parsed - value).abs() < 1e-4);
        }
    }

    /// Fuzz targets: telemetry parsing takes any payload without panicking, and a frame it
    /// accepts has finite numbers and one position per sample.
    mod fuzz {
        use proptest::prelude::*;
        use rover_fuzzing::mutation::mutated_text;

        use super::*;

        /// Names of the real fields, and a few others.
        fn field_name() -> impl Strategy<Value = String> {
            let names = sample_payload().keys().cloned().chain(["".into(), "x".into()]).collect::<Vec<_>>();
            prop_oneof![4 => proptest::sample::select(names), 1 => "\\PC{0,8}"]
        }

        /// Text that looks like a number, a list or a position, or anything.
        fn field_text() -> impl Strategy<Value = String> {
            prop_oneof![
                any::<f64>().prop_map(|v| v.to_string()),
                "[-0-9.,;eE ]{0,24}",
                Just("NaN".to_string()),
                Just("inf;-inf".to_string()),
                "\\PC{0,24}",
            ]
        }

        /// A JSON value a field might hold: text, a number, a boolean, null or a list.
        fn field_value() -> impl Strategy<Value = Value> {
            prop_oneof![
                6 => field_text().prop_map(Value::String),
                1 => any::<f64>().prop_map(Value::from),
                1 => any::<bool>().prop_map(Value::Bool),
                1 => Just(Value::Null),
                1 => Just(serde_json::json!(["1.0"])),
            ]
        }

        /// The valid frame with some fields replaced or removed, and maybe some added.
        fn edited_payload() -> impl Strategy<Value = Map<String, Value>> {
            let edits = proptest::collection::vec((field_name(), proptest::option::of(field_value())), 0..8);
            edits.prop_map(|edits| {
                let mut fields = sample_payload();
                for (name, value) in edits {
                    match value {
                        Some(value) => fields.insert(name, value),
                        None => fields.remove(&name),
                    };
                }
                fields
            })
        }

        /// An accepted frame has finite numbers and one (x, y) per sample.
        fn check(payload: &str) -> Result<(), TestCaseError> {
            if let Ok(Some(t)) = parse_telemetry(payload, 1 << 20) {
                let numbers = [
                    t.state.steering_angle_deg,
                    t.state.throttle,
                    t.state.brake,
                    t.state.speed_mps,
                    t.state.x_m,
                    t.state.y_m,
                    t.state.pitch_deg,
                    t.state.yaw_deg,
                ];
                prop_assert!(numbers.iter().chain([&t.state.roll_deg]).all(|v| v.is_finite()));
                prop_assert!(t.samples.iter().all(|(x, y)| x.is_finite() && y.is_finite()));
            }
            Ok(())
        }

        proptest! {
            #[test]
            fn fuzz_telemetry_arbitrary_payloads(payload in "\\PC{0,300}") {
                check(&payload)?;
            }

            #[test]
            fn fuzz_telemetry_arbitrary_objects(fields in proptest::collection::btree_map(field_name(), field_value(), 0..16)) {
                check(&serde_json::to_string(&fields).unwrap())?;
            }

            #[test]
            fn fuzz_telemetry_edited_frames(fields in edited_payload()) {
                check(&serde_json::to_string(&fields).unwrap())?;
            }

            #[test]
            fn fuzz_telemetry_mutated_frames(payload in mutated_text(vec![serde_json::to_string(&sample_payload()).unwrap()])) {
                check(&payload)?;
            }
        }
    }
}
