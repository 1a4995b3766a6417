//! Engine.IO / Socket.IO text packets as the Unity client encodes and decodes them
//! (unity-sim-spec 1.2): single-digit control packets, `42["event",{...}]` events.

use serde_json::Value;

/// Engine.IO PING.
pub const PING: &str = "2";
/// Engine.IO PONG.
pub const PONG: &str = "3";
/// Socket.IO DISCONNECT of the default namespace, sent before closing.
pub const DISCONNECT: &str = "41";
/// Engine.IO CLOSE.
pub const CLOSE: &str = "1";

/// A decoded packet from the server.
#[derive(Debug, Clone, PartialEq)]
pub enum Inbound {
    /// Engine.IO OPEN (the handshake; the websocket transport needs nothing from it).
    Open,
    /// Engine.IO PING: answer with PONG.
    Ping,
    /// Engine.IO PONG: the answer to our ping.
    Pong,
    /// Engine.IO CLOSE.
    Close,
    /// A Socket.IO event with its optional object argument.
    Event {
        /// Event name.
        name: String,
        /// The argument, if the array had a second element.
        data: Option<Value>,
    },
    /// A packet the client ignores (CONNECT, NOOP, ACK...), with the reason.
    Ignored(&'static str),
    /// An event the Unity parser would throw on (not an array, element 0 not a string,
    /// element 1 not an object): it is dropped and gets no telemetry.
    Malformed(String),
}

/// Encodes an event as the Unity client does: `42["name",json]` (no namespace, no ack id).
pub fn encode_event(name: &str, json_object: &str) -> String {
    let mut packet = String::with_capacity(json_object.len() + name.len() + 8);
    packet.push_str("42[\"");
    packet.push_str(name);
    packet.push_str("\",");
    packet.push_str(json_object);
    packet.push(']');
    packet
}

/// Decodes one websocket text message the way the Unity client's `Decoder` and `Parser` do.
pub fn decode(text: &str) -> Inbound {
    let mut chars = text.chars();
    match chars.next() {
        Some('0') => Inbound::Open,
        Some('1') => Inbound::Close,
        Some('2') => Inbound::Ping,
        Some('3') => Inbound::Pong,
        Some('4') => decode_message(&text[1..]),
        Some('6') => Inbound::Ignored("noop"),
        _ => Inbound::Ignored("unknown Engine.IO packet type"),
    }
}

fn decode_message(body: &str) -> Inbound {
    if body.len() <= 1 {
        return Inbound::Ignored("Socket.IO packet without payload");
    }
    let mut chars = body.chars();
    match chars.next() {
        Some('2') => {}
        Some('0') => return Inbound::Ignored("Socket.IO CONNECT"),
        _ => return Inbound::Ignored("Socket.IO packet other than EVENT"),
    }
    let mut rest = chars.as_str();
    if rest.starts_with('/')
        && let Some(comma) = rest.find(',')
    {
        rest = &rest[comma + 1..];
    }
    let rest = rest.trim_start_matches(|c: char| c.is_ascii_digit());
    let Ok(Value::Array(mut items)) = serde_json::from_str::<Value>(rest) else {
        return Inbound::Malformed("event payload is not a JSON array".to_string());
    };
    if items.is_empty() || items.len() > 2 {
        return Inbound::Malformed(format!("event array has {} elements, expected 1 or 2", items.len()));
    }
    let data = if items.len() == 2 { items.pop() } else { None };
    let Some(Value::String(name)) = items.pop() else {
        return Inbound::Malformed("event name is not a string".to_string());
    };
    match data {
        Some(Value::Object(_)) | None => Inbound::Event { name, data },
        Some(_) => Inbound::Malformed(format!("argument of event {name:?} is not a JSON object")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn control_packets() {
        assert_eq!(decode("0{\"sid\":\"abc\",\"pingInterval\":25000}"), Inbound::Open);
        assert_eq!(decode("2"), Inbound::Ping);
        assert_eq!(decode("3"), Inbound::Pong);
        assert_eq!(decode("1"), Inbound::Close);
        assert_eq!(decode("40"), Inbound::Ignored("Socket.IO packet without payload"));
        assert!(matches!(decode("40{\"sid\":\"x\"}"), Inbound::Ignored(_)));
    }

    #[test]
    fn events_with_and_without_data() {
        let data = decode("42[\"data\",{\"throttle\":\"0.2\"}]");
        assert_eq!(data, Inbound::Event { name: "data".into(), data: Some(serde_json::json!({"throttle": "0.2"})) });
        assert_eq!(decode("42[\"manual\"]"), Inbound::Event { name: "manual".into(), data: None });
        assert_eq!(
            decode("42/ns,17[\"pickup\",{}]"),
            Inbound::Event { name: "pickup".into(), data: Some(serde_json::json!({})) }
        );
    }

    #[test]
    fn malformed_events_are_dropped() {
        assert!(matches!(decode("42[\"data\",5]"), Inbound::Malformed(_)));
        assert!(matches!(decode("42[5]"), Inbound::Malformed(_)));
        assert!(matches!(decode("42{\"a\":1}"), Inbound::Malformed(_)));
        assert!(matches!(decode("42[\"a\",{},{}]"), Inbound::Malformed(_)));
    }

    #[test]
    fn a_multibyte_socket_io_type_is_ignored() {
        assert_eq!(decode("4\u{fffd}2[\"data\"]"), Inbound::Ignored("Socket.IO packet other than EVENT"));
    }

    #[test]
    fn events_are_encoded_compactly() {
        assert_eq!(encode_event("telemetry", "{\"a\":\"1\"}"), "42[\"telemetry\",{\"a\":\"1\"}]");
    }

    /// Fuzz targets: the client decodes any message without panicking, and an event it accepts
    /// came in a `42` message with at most an object argument.
    mod fuzz {
        use proptest::prelude::*;
        use rover_fuzzing::mutation::mutated_text;

        use super::*;

        /// Valid messages of every kind, to mutate.
        fn valid_messages() -> Vec<String> {
            let events = [encode_event("data", "{\"throttle\":\"0.2\"}"), "42/ns,17[\"manual\"]".to_string()];
            ["0{\"sid\":\"abc\"}", "1", "2", "3", "40", "6"].map(String::from).into_iter().chain(events).collect()
        }

        /// An accepted event came in a `42` message and its argument, if any, is an object.
        fn check(text: &str) -> Result<(), TestCaseError> {
            if let Inbound::Event { data, .. } = decode(text) {
                prop_assert!(text.starts_with("42"));
                prop_assert!(data.is_none_or(|data| data.is_object()));
            }
            Ok(())
        }

        proptest! {
            #[test]
            fn fuzz_sim_packet_arbitrary_text(text in "\\PC{0,64}") {
                check(&text)?;
            }

            #[test]
            fn fuzz_sim_packet_mutated_messages(text in mutated_text(valid_messages())) {
                check(&text)?;
            }
        }
    }
}
