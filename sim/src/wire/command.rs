//! The commands the simulator accepts (unity-sim-spec 1.4), parsed as strictly as the Unity
//! `CommandServer`: every value must be a JSON string; a number or a missing required field
//! makes the handler throw, so the command is dropped and no telemetry is sent.

use serde_json::Value;

/// A command from the server.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// `data`: drive with these inputs until the next command.
    Drive {
        /// Steering angle, degrees, positive left (clamped to +-15 by the rover).
        steering_deg: f64,
        /// Throttle (not clamped).
        throttle: f64,
        /// Brake (not clamped).
        brake: f64,
    },
    /// `manual`: no change, just answer with telemetry.
    Manual,
    /// `pickup`: start picking up the sample within reach, if any.
    Pickup,
    /// `fixed_turn`: turn in place by `angle_deg` over `time_s` (clockwise for a positive angle).
    FixedTurn {
        /// Angle, degrees, positive clockwise.
        angle_deg: f64,
        /// Duration, seconds (0 means angle / 45).
        time_s: f64,
    },
}

/// Why a command was dropped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CommandError {
    /// The event carried no object where fields are required.
    #[error("`{0}` needs an object argument")]
    NoArgument(&'static str),
    /// A required field is absent.
    #[error("`{event}` field `{field}` is missing")]
    MissingField {
        /// Event name.
        event: &'static str,
        /// Field name.
        field: &'static str,
    },
    /// A field is not a JSON string (Unity's `JSONObject.str` is null for numbers).
    #[error("`{event}` field `{field}` is not a JSON string")]
    NotAString {
        /// Event name.
        event: &'static str,
        /// Field name.
        field: &'static str,
    },
    /// A field's text is not a number.
    #[error("`{event}` field `{field}` = {text:?} is not a number")]
    NotANumber {
        /// Event name.
        event: &'static str,
        /// Field name.
        field: &'static str,
        /// The text.
        text: String,
    },
}

/// Parses an event. `Ok(None)` means the simulator ignores the event (no telemetry).
pub fn parse_command(name: &str, data: Option<&Value>) -> Result<Option<Command>, CommandError> {
    match name {
        "data" => {
            let data = data.ok_or(CommandError::NoArgument("data"))?;
            Ok(Some(Command::Drive {
                steering_deg: required("data", data, "steering_angle")?,
                throttle: required("data", data, "throttle")?,
                brake: optional("data", data, "brake")?.unwrap_or(0.0),
            }))
        }
        "manual" => Ok(Some(Command::Manual)),
        "pickup" => Ok(Some(Command::Pickup)),
        "fixed_turn" => {
            let data = data.ok_or(CommandError::NoArgument("fixed_turn"))?;
            Ok(Some(Command::FixedTurn {
                angle_deg: required("fixed_turn", data, "angle")?,
                time_s: optional("fixed_turn", data, "time")?.unwrap_or(0.0),
            }))
        }
        _ => Ok(None),
    }
}

fn required(event: &'static str, data: &Value, field: &'static str) -> Result<f64, CommandError> {
    optional(event, data, field)?.ok_or(CommandError::MissingField { event, field })
}

fn optional(event: &'static str, data: &Value, field: &'static str) -> Result<Option<f64>, CommandError> {
    match data.get(field) {
        None => Ok(None),
        Some(Value::String(text)) => {
            parse_float(text).map(Some).ok_or_else(|| CommandError::NotANumber { event, field, text: text.clone() })
        }
        Some(_) => Err(CommandError::NotAString { event, field }),
    }
}

/// Parses a number leniently, as the spec asks for Python `str()` output: `0.2`, `-15.0`, `10`,
/// `1e-05`; `nan` and infinities read as 0 (a rover cannot apply them).
fn parse_float(text: &str) -> Option<f64> {
    let value: f64 = text.trim().parse().ok()?;
    Some(if value.is_finite() { value } else { 0.0 })
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn drive_command_with_default_brake() {
        let command = parse_command("data", Some(&json!({"steering_angle": "-4.37", "throttle": "0.2"}))).unwrap();
        assert_eq!(command, Some(Command::Drive { steering_deg: -4.37, throttle: 0.2, brake: 0.0 }));
    }

    #[test]
    fn numbers_and_missing_fields_drop_the_command() {
        let number = parse_command("data", Some(&json!({"steering_angle": 0, "throttle": "0"})));
        assert_eq!(number, Err(CommandError::NotAString { event: "data", field: "steering_angle" }));
        let missing = parse_command("data", Some(&json!({"steering_angle": "0"})));
        assert_eq!(missing, Err(CommandError::MissingField { event: "data", field: "throttle" }));
        assert_eq!(parse_command("data", None), Err(CommandError::NoArgument("data")));
        assert!(parse_command("data", Some(&json!({"steering_angle": "x", "throttle": "0"}))).is_err());
    }

    #[test]
    fn nan_is_read_leniently() {
        let command = parse_command("data", Some(&json!({"steering_angle": "nan", "throttle": "0.2"}))).unwrap();
        assert_eq!(command, Some(Command::Drive { steering_deg: 0.0, throttle: 0.2, brake: 0.0 }));
    }

    #[test]
    fn other_events() {
        assert_eq!(parse_command("manual", None).unwrap(), Some(Command::Manual));
        assert_eq!(parse_command("pickup", Some(&json!({}))).unwrap(), Some(Command::Pickup));
        assert_eq!(
            parse_command("fixed_turn", Some(&json!({"angle": "90"}))).unwrap(),
            Some(Command::FixedTurn { angle_deg: 90.0, time_s: 0.0 })
        );
        assert_eq!(parse_command("get_samples", Some(&json!({}))).unwrap(), None);
        assert_eq!(parse_command("whatever", None).unwrap(), None);
    }

    /// Fuzz targets: any event name and argument gives a command or an error, never a panic, and
    /// an accepted command holds finite numbers only.
    mod fuzz {
        use proptest::prelude::*;

        use super::*;

        /// A field value: a number as text (maybe not finite), any text, a number or null.
        fn field_value() -> impl Strategy<Value = Value> {
            prop_oneof![
                4 => any::<f64>().prop_map(|v| Value::String(v.to_string())),
                2 => "\\PC{0,12}".prop_map(Value::String),
                1 => prop_oneof![Just("nan"), Just("-inf"), Just(" 1e-05 "), Just("1e999")].prop_map(Value::from),
                1 => any::<f64>().prop_map(Value::from),
                1 => Just(Value::Null),
            ]
        }

        /// An argument object over the commands' field names, or a value that is no object.
        fn argument() -> impl Strategy<Value = Option<Value>> {
            let names = proptest::sample::select(vec!["steering_angle", "throttle", "brake", "angle", "time", "x"]);
            let object = proptest::collection::btree_map(names, field_value(), 0..6)
                .prop_map(|fields| Value::from_iter(fields.into_iter().map(|(k, v)| (k.to_string(), v))));
            proptest::option::of(prop_oneof![4 => object, 1 => field_value()])
        }

        fn event_name() -> impl Strategy<Value = String> {
            let names = vec!["data", "manual", "pickup", "fixed_turn", "get_samples"];
            prop_oneof![4 => proptest::sample::select(names).prop_map(String::from), 1 => "\\PC{0,12}"]
        }

        /// Every number of a command is finite.
        fn is_finite(command: &Command) -> bool {
            match *command {
                Command::Drive { steering_deg, throttle, brake } => {
                    [steering_deg, throttle, brake].iter().all(|v| v.is_finite())
                }
                Command::FixedTurn { angle_deg, time_s } => angle_deg.is_finite() && time_s.is_finite(),
                Command::Manual | Command::Pickup => true,
            }
        }

        proptest! {
            #[test]
            fn fuzz_sim_command_arbitrary_arguments(name in event_name(), data in argument()) {
                if let Ok(Some(command)) = parse_command(&name, data.as_ref()) {
                    prop_assert!(is_finite(&command), "{command:?}");
                }
            }
        }
    }
}
