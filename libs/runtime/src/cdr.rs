//! The bytes of a message exactly as ros2-client publishes it: the 4-byte encapsulation header
//! (CDR little endian, no options) and the CDR payload of RustDDS's serializer, and back.

use ros2_client::dds::rustdds::bytes::Bytes;
use ros2_client::dds::rustdds::no_key::SerializerAdapter as _;
use ros2_client::dds::rustdds::serialization::deserialize_from_cdr_with_rep_id;
use ros2_client::dds::rustdds::{CDRSerializerAdapter, RepresentationIdentifier, SerializedPayload};
use rover_msgs::RosMessage;

/// Length of the encapsulation header: representation identifier and options, 2 bytes each.
const HEADER_LEN: usize = 4;

/// Serializes `message` as a publisher of ros2-client puts it on the wire.
pub fn encode<M: RosMessage>(message: &M) -> anyhow::Result<Vec<u8>> {
    let payload = CDRSerializerAdapter::<M>::to_bytes(message)
        .map_err(|e| anyhow::anyhow!("cannot serialize a {}: {e}", M::type_name()))?;
    let serialized = SerializedPayload::new_from_bytes(CDRSerializerAdapter::<M>::output_encoding(), payload);
    Ok(Bytes::from(serialized).to_vec())
}

/// Deserializes the bytes of one message (encapsulation header and CDR payload, either byte order).
pub fn decode<M: RosMessage>(bytes: &[u8]) -> anyhow::Result<M> {
    anyhow::ensure!(
        bytes.len() >= HEADER_LEN,
        "a {} message of {} bytes is shorter than the {HEADER_LEN}-byte encapsulation header",
        M::type_name(),
        bytes.len()
    );
    let representation = RepresentationIdentifier::from_bytes(&bytes[..2])?;
    let (message, _) = deserialize_from_cdr_with_rep_id::<M>(&bytes[HEADER_LEN..], representation)
        .map_err(|e| anyhow::anyhow!("cannot deserialize a {}: {e}", M::type_name()))?;
    Ok(message)
}

#[cfg(test)]
mod tests {
    use rover_msgs::msg::Telemetry;
    use rover_msgs::nav_msgs::OccupancyGrid;
    use rover_msgs::std_msgs::Header;

    use super::*;

    #[test]
    fn a_message_round_trips_behind_the_cdr_little_endian_header() {
        let telemetry = Telemetry { header: Header::now("odom"), frame: 7, x_m: 99.5, ..Telemetry::default() };
        let bytes = encode(&telemetry).unwrap();
        assert_eq!(bytes[..4], [0, 1, 0, 0]);
        assert_eq!(decode::<Telemetry>(&bytes).unwrap(), telemetry);
    }

    #[test]
    fn an_occupancy_grids_cells_go_as_a_cdr_int8_sequence_a_length_and_a_byte_each() {
        let grid = OccupancyGrid { data: vec![-1, 0, 100, 50, -1], ..OccupancyGrid::default() };
        let bytes = encode(&grid).unwrap();
        assert_eq!(bytes[bytes.len() - 9..], [5, 0, 0, 0, 0xFF, 0, 100, 50, 0xFF]);
        assert_eq!(decode::<OccupancyGrid>(&bytes).unwrap(), grid);
        let mut truncated = bytes.clone();
        truncated.truncate(bytes.len() - 1);
        assert!(decode::<OccupancyGrid>(&truncated).is_err(), "a cell short");
    }

    #[test]
    fn short_or_truncated_bytes_are_errors_naming_the_type() {
        let error = decode::<Telemetry>(&[0, 1]).unwrap_err().to_string();
        assert!(error.contains("rover_msgs/msg/Telemetry") && error.contains("header"), "{error}");
        let bytes = encode(&Telemetry::default()).unwrap();
        assert!(decode::<Telemetry>(&bytes[..bytes.len() - 3]).is_err());
    }
}
