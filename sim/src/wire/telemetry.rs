//! The telemetry event as the Unity `CommandServer` writes it (unity-sim-spec 2): compact JSON,
//! every value a string, numbers in .NET "N4" (invariant culture), `x;y` position, `;` lists.

use std::fmt::Write as _;

use base64::Engine as _;
use rover_msgs::unity::ReportedState;

use crate::physics::wrap_degrees;

/// The values of one telemetry event, in the simulator's conventions.
#[derive(Debug, Clone, PartialEq)]
pub struct TelemetryValues<'a> {
    /// Controls and pose.
    pub state: ReportedState,
    /// A sample is within reach.
    pub near_sample: bool,
    /// A pickup is running.
    pub picking_up: bool,
    /// Samples still on the ground, with their positions.
    pub samples: &'a [(f64, f64)],
    /// Camera JPEG.
    pub image_jpeg: &'a [u8],
}

/// Formats like .NET `ToString("N4")` in the invariant culture: `1,234.5678`, `-0.5000`, `0.0000`.
pub fn n4(value: f64) -> String {
    format_grouped(value, 4)
}

/// Formats like .NET `ToString("N2")`.
pub fn n2(value: f64) -> String {
    format_grouped(value, 2)
}

fn format_grouped(value: f64, decimals: usize) -> String {
    let text = format!("{:.*}", decimals, value.abs());
    let (integer, fraction) = text.split_once('.').unwrap_or((&text, ""));
    let negative = value < 0.0 && text.bytes().any(|b| (b'1'..=b'9').contains(&b));
    let mut out = String::with_capacity(text.len() + 4);
    if negative {
        out.push('-');
    }
    for (index, digit) in integer.chars().enumerate() {
        if index > 0 && (integer.len() - index).is_multiple_of(3) {
            out.push(',');
        }
        out.push(digit);
    }
    if decimals > 0 {
        out.push('.');
        out.push_str(fraction);
    }
    out
}

impl TelemetryValues<'_> {
    /// The JSON object of the `telemetry` event, keys in the Unity order.
    pub fn to_json(&self) -> String {
        let mut json = String::with_capacity(self.image_jpeg.len() * 4 / 3 + 512);
        let mut field = |key: &str, value: &str| {
            json.push(if json.is_empty() { '{' } else { ',' });
            let _ = write!(json, "\"{key}\":\"{value}\"");
        };
        field("steering_angle", &n4(self.state.steering_angle_deg));
        field("throttle", &n4(self.state.throttle));
        field("brake", &n4(self.state.brake));
        field("speed", &n4(self.state.speed_mps));
        field("position", &format!("{};{}", n4(self.state.x_m), n4(self.state.y_m)));
        field("pitch", &n4(wrap_degrees(self.state.pitch_deg)));
        field("yaw", &n4(wrap_degrees(self.state.yaw_deg)));
        field("roll", &n4(wrap_degrees(self.state.roll_deg)));
        field("near_sample", if self.near_sample { "1" } else { "0" });
        field("picking_up", if self.picking_up { "1" } else { "0" });
        field("sample_count", &self.samples.len().to_string());
        field("samples_x", &join(self.samples.iter().map(|s| n2(s.0))));
        field("samples_y", &join(self.samples.iter().map(|s| n2(s.1))));
        field("image", &base64::engine::general_purpose::STANDARD.encode(self.image_jpeg));
        json.push('}');
        json
    }
}

fn join(items: impl Iterator<Item = String>) -> String {
    items.collect::<Vec<_>>().join(";")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn n4_matches_dotnet_invariant() {
        assert_eq!(n4(0.0), "0.0000");
        assert_eq!(n4(-0.00001), "0.0000");
        assert_eq!(n4(-4.372158), "-4.3722");
        assert_eq!(n4(1234.56789), "1,234.5679");
        assert_eq!(n4(-1234567.0), "-1,234,567.0000");
        assert_eq!(n2(97.444), "97.44");
    }

    #[test]
    fn angles_wrap_like_euler_angles() {
        assert_eq!(wrap_degrees(-0.5), 359.5);
        assert_eq!(wrap_degrees(360.0), 0.0);
        assert_eq!(wrap_degrees(56.8255), 56.8255);
    }

    #[test]
    fn json_has_every_key_as_a_string_in_unity_order() {
        let samples = [(97.44, 74.65), (122.28, 51.66)];
        let values = TelemetryValues {
            state: ReportedState {
                x_m: 99.67,
                y_m: 85.589,
                pitch_deg: -0.5,
                yaw_deg: 56.8255,
                ..ReportedState::default()
            },
            near_sample: false,
            picking_up: false,
            samples: &samples,
            image_jpeg: &[0xFF, 0xD8, 0xFF, 0xD9],
        };
        let json = values.to_json();
        assert!(json.starts_with("{\"steering_angle\":\"0.0000\",\"throttle\":\"0.0000\",\"brake\":\"0.0000\",\"speed\":\"0.0000\",\"position\":\"99.6700;85.5890\",\"pitch\":\"359.5000\""), "{json}");
        assert!(json.contains("\"sample_count\":\"2\",\"samples_x\":\"97.44;122.28\",\"samples_y\":\"74.65;51.66\",\"image\":\"/9j/2Q==\"}"), "{json}");
        let parsed: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert!(parsed.as_object().unwrap().values().all(|v| v.is_string()));
        assert!(!json.contains(' '));
    }
}
