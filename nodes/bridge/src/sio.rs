//! Socket.IO protocol v4 packets as the server sees them inside Engine.IO 3 messages:
//! `0` CONNECT, `1` DISCONNECT, `2["event",args...]` EVENT (optional `/nsp,` and ack id).

use serde_json::Value;

/// A decoded Socket.IO packet from the simulator.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Packet {
    /// Namespace CONNECT (the Unity client never sends it).
    Connect,
    /// Namespace DISCONNECT (sent before the client quits).
    Disconnect,
    /// An event with its arguments.
    Event {
        /// Event name.
        name: String,
        /// Arguments after the name.
        args: Vec<Value>,
    },
    /// ACK or ERROR packets, which the bridge does not use.
    Other(char),
}

/// Why a message is not a Socket.IO packet.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub(crate) enum PacketError {
    /// Empty message.
    #[error("empty Socket.IO packet")]
    Empty,
    /// Unknown packet type digit.
    #[error("unknown Socket.IO packet type {0:?}")]
    UnknownType(char),
    /// Binary events are not part of the simulator's dialect.
    #[error("binary Socket.IO events are not supported")]
    Binary,
    /// The event payload is not a JSON array starting with a string.
    #[error("Socket.IO event payload is not [\"name\", ...]: {0}")]
    BadEvent(String),
}

/// Decodes the text of one Engine.IO message as a Socket.IO packet.
pub(crate) fn decode(text: &str) -> Result<Packet, PacketError> {
    let mut chars = text.chars();
    let kind = chars.next().ok_or(PacketError::Empty)?;
    match kind {
        '0' => Ok(Packet::Connect),
        '1' => Ok(Packet::Disconnect),
        '2' => decode_event(chars.as_str()),
        '3' | '4' => Ok(Packet::Other(kind)),
        '5' | '6' => Err(PacketError::Binary),
        other => Err(PacketError::UnknownType(other)),
    }
}

fn decode_event(body: &str) -> Result<Packet, PacketError> {
    let mut body = body;
    if body.starts_with('/')
        && let Some(comma) = body.find(',')
    {
        body = &body[comma + 1..];
    }
    let body = body.trim_start_matches(|c: char| c.is_ascii_digit());
    let value: Value = serde_json::from_str(body).map_err(|e| PacketError::BadEvent(e.to_string()))?;
    let Value::Array(mut items) = value else {
        return Err(PacketError::BadEvent("not an array".to_string()));
    };
    if items.is_empty() {
        return Err(PacketError::BadEvent("empty array".to_string()));
    }
    let args = items.split_off(1);
    match items.pop() {
        Some(Value::String(name)) => Ok(Packet::Event { name, args }),
        _ => Err(PacketError::BadEvent("the event name is not a string".to_string())),
    }
}

/// Encodes an event with one argument: `2["name",argument]`.
pub(crate) fn encode_event(name: &str, argument: &impl serde::Serialize) -> Result<String, serde_json::Error> {
    let argument = serde_json::to_string(argument)?;
    let name = serde_json::to_string(name)?;
    Ok(format!("2[{name},{argument}]"))
}

/// The CONNECT packet a protocol-v4 server sends for the default namespace.
pub(crate) const CONNECT: &str = "0";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn events_with_namespace_and_ack_id() {
        assert_eq!(
            decode("2[\"telemetry\",{\"a\":\"1\"}]").unwrap(),
            Packet::Event { name: "telemetry".into(), args: vec![serde_json::json!({"a": "1"})] }
        );
        assert_eq!(decode("2/,12[\"manual\"]").unwrap(), Packet::Event { name: "manual".into(), args: vec![] });
        assert_eq!(decode("0").unwrap(), Packet::Connect);
        assert_eq!(decode("1").unwrap(), Packet::Disconnect);
    }

    #[test]
    fn bad_packets_are_named() {
        assert_eq!(decode(""), Err(PacketError::Empty));
        assert_eq!(decode("9"), Err(PacketError::UnknownType('9')));
        assert_eq!(decode("51-[\"x\",{}]"), Err(PacketError::Binary));
        assert!(matches!(decode("2[\"telemetry\",{\"speed\":\"1\",]"), Err(PacketError::BadEvent(_))));
        assert!(matches!(decode("2[5]"), Err(PacketError::BadEvent(_))));
        assert!(matches!(decode("2{}"), Err(PacketError::BadEvent(_))));
    }

    #[test]
    fn encodes_compact_events() {
        let text = encode_event("data", &serde_json::json!({"throttle": "0.2"})).unwrap();
        assert_eq!(text, "2[\"data\",{\"throttle\":\"0.2\"}]");
        assert_eq!(
            decode(&text).unwrap(),
            Packet::Event { name: "data".into(), args: vec![serde_json::json!({"throttle": "0.2"})] }
        );
    }

    /// Fuzz targets: the decoder takes any text without panicking, and an event it accepts has
    /// the name and arguments of a `2["name",...]` array.
    mod fuzz {
        use proptest::prelude::*;
        use rover_fuzzing::mutation::mutated_text;

        use super::*;

        /// Valid packets of every kind, to mutate.
        fn valid_packets() -> Vec<String> {
            ["0", "1", "2[\"telemetry\",{\"speed\":\"1.0\"}]", "2/,12[\"manual\"]", "3", "4"].map(String::from).to_vec()
        }

        /// An accepted packet is of the kind its first character names.
        fn check(text: &str) -> Result<(), TestCaseError> {
            let kind = match decode(text) {
                Ok(Packet::Connect) => '0',
                Ok(Packet::Disconnect) => '1',
                Ok(Packet::Event { .. }) => '2',
                Ok(Packet::Other(kind)) => kind,
                Err(_) => return Ok(()),
            };
            prop_assert!(text.starts_with(kind));
            Ok(())
        }

        proptest! {
            #[test]
            fn fuzz_sio_decode_arbitrary_text(text in "\\PC{0,64}") {
                check(&text)?;
            }

            #[test]
            fn fuzz_sio_decode_arbitrary_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
                check(&String::from_utf8_lossy(&bytes))?;
            }

            #[test]
            fn fuzz_sio_decode_mutated_packets(text in mutated_text(valid_packets())) {
                check(&text)?;
            }
        }
    }
}
