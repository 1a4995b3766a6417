//! The mapping node's memory on disk: the map's evidence, home and the collected count, so that a
//! node restarted after a crash carries on where the last one stopped (a snapshot file of
//! [`rover_runtime::snapshot`], layout in [`encode`]).

use rover_msgs::map_grid::CELLS;
use rover_msgs::tally::SampleTally;
use rover_runtime::snapshot::{Fields, SnapshotError, Writer};

use crate::map::{CLASSES, Evidence, WEIGHED};

/// The first bytes of a snapshot: the format and its version.
const MAGIC: &[u8; 8] = b"RVRMAP02";
/// The snapshot's file name in the state folder.
pub(crate) const FILE_NAME: &str = "mapping.snapshot";

/// Where the rover started: the frame, then world metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Home {
    /// Lock-step frame of the first telemetry.
    pub frame: u64,
    /// World x, metres.
    pub x_m: f64,
    /// World y, metres.
    pub y_m: f64,
}

/// Everything the mapping node must not lose across a restart.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Memory {
    /// The map's evidence.
    pub evidence: Evidence,
    /// Where the rover started, once known.
    pub home: Option<Home>,
    /// The collected count and the last `samples_remaining`.
    pub tally: SampleTally,
    /// Where the samples were collected, world metres.
    pub collected_at: Vec<(f64, f64)>,
}

/// The bytes of `memory`: the magic, the cell count (u64), home (flag u8, frame u64, x f64, y f64),
/// the tally (collected u32, flag u8, last remaining u8), then per class the hits (u16 per cell),
/// per weighed class the weights (f32 per cell), the rock ranges (f32 per cell), then the places
/// of the collected samples (count u8, then x f64 and y f64 each).
pub(crate) fn encode(memory: &Memory) -> Vec<u8> {
    let mut out = Writer::new(MAGIC);
    out.bytes.reserve(64 + CELLS * (2 * CLASSES + 4 * WEIGHED + 4));
    out.u64(CELLS as u64);
    let home = memory.home.unwrap_or(Home { frame: 0, x_m: 0.0, y_m: 0.0 });
    out.flag(memory.home.is_some());
    out.u64(home.frame);
    out.f64(home.x_m);
    out.f64(home.y_m);
    out.u32(memory.tally.collected());
    out.flag(memory.tally.last_remaining().is_some());
    out.u8(memory.tally.last_remaining().unwrap_or(0));
    let evidence = &memory.evidence;
    evidence.hits.iter().flatten().for_each(|&h| out.u16(h));
    evidence.weight.iter().flatten().for_each(|&w| out.f32(w));
    evidence.rock_range_m.iter().for_each(|&r| out.f32(r));
    let places = &memory.collected_at[..memory.collected_at.len().min(u8::MAX as usize)];
    out.u8(places.len() as u8);
    places.iter().for_each(|&place| out.place_m(place));
    out.bytes
}

/// Reads `bytes` back into a memory, checking the layout and every value.
pub(crate) fn decode(bytes: &[u8]) -> Result<Memory, SnapshotError> {
    let mut fields = Fields::after_magic(bytes, MAGIC)?;
    fields.expect_u64("cell count", CELLS as u64)?;
    let has_home = fields.flag("home flag")?;
    let home = Home { frame: fields.u64("home frame")?, x_m: fields.f64("home x")?, y_m: fields.f64("home y")? };
    if has_home && !(home.x_m.is_finite() && home.y_m.is_finite()) {
        return Err(SnapshotError::BadValue("home", format!("({}, {})", home.x_m, home.y_m), "finite metres"));
    }
    let collected = fields.u32("collected count")?;
    let has_last = fields.flag("tally flag")?;
    let last_remaining = fields.u8("samples remaining")?;
    let mut evidence = Evidence::empty();
    for hits in evidence.hits.iter_mut().flatten() {
        *hits = fields.u16("hits")?;
    }
    for weight in evidence.weight.iter_mut().flatten() {
        *weight = fields.f32("weights")?;
        if !(weight.is_finite() && *weight >= 0.0) {
            return Err(SnapshotError::BadValue("weights", weight.to_string(), "finite and >= 0"));
        }
    }
    for range_m in &mut evidence.rock_range_m {
        *range_m = fields.f32("rock ranges")?;
        if range_m.is_nan() || *range_m < 0.0 {
            return Err(SnapshotError::BadValue("rock ranges", range_m.to_string(), ">= 0 m or infinite"));
        }
    }
    let places = fields.u8("collected places")?;
    let collected_at = (0..places).map(|_| fields.place_m("collected places")).collect::<Result<_, _>>()?;
    fields.finish()?;
    Ok(Memory {
        evidence,
        home: has_home.then_some(home),
        tally: SampleTally::resumed(collected, has_last.then_some(last_remaining)),
        collected_at,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn memory() -> Memory {
        let mut evidence = Evidence::empty();
        evidence.hits[0][17] = 3;
        evidence.hits[1][CELLS - 1] = 65_535;
        evidence.hits[2][400] = 2;
        evidence.weight[0][17] = 2.5;
        evidence.weight[1][CELLS - 1] = 0.125;
        evidence.rock_range_m[400] = 1.75;
        Memory {
            evidence,
            home: Some(Home { frame: 3, x_m: 99.7, y_m: 85.2 }),
            tally: SampleTally::resumed(2, Some(4)),
            collected_at: vec![(97.5, 74.25), (122.0, 51.5)],
        }
    }

    #[test]
    fn a_snapshot_reads_back_as_written() {
        let memory = memory();
        assert_eq!(decode(&encode(&memory)), Ok(memory.clone()));
        let fresh =
            Memory { evidence: Evidence::empty(), home: None, tally: SampleTally::default(), collected_at: Vec::new() };
        assert_eq!(decode(&encode(&fresh)), Ok(fresh));
    }

    #[test]
    fn damaged_snapshots_are_refused_with_the_field_named() {
        let bytes = encode(&memory());
        assert_eq!(
            decode(&bytes[..bytes.len() - 1]),
            Err(SnapshotError::Truncated(bytes.len() - 1, "collected places"))
        );
        assert_eq!(decode(&bytes[..20]), Err(SnapshotError::Truncated(20, "home frame")));
        assert_eq!(decode(b"GIF89a.."), Err(SnapshotError::NotASnapshot(MAGIC)));
        let mut longer = bytes.clone();
        longer.push(0);
        assert_eq!(decode(&longer), Err(SnapshotError::TrailingBytes(1)));
        let mut nan_weight = bytes.clone();
        let first_weight = 8 + 8 + 25 + 6 + 2 * CLASSES * CELLS;
        nan_weight[first_weight..first_weight + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(matches!(decode(&nan_weight), Err(SnapshotError::BadValue("weights", ..))));
        let mut bad_flag = bytes;
        bad_flag[16] = 7;
        assert!(matches!(decode(&bad_flag), Err(SnapshotError::BadValue("home flag", ..))));
    }

    mod fuzz {
        use proptest::prelude::*;
        use rover_fuzzing::mutation::mutated_bytes;

        use super::*;

        /// Bytes before the cells: magic, cell count, home, tally.
        const HEADER: usize = 8 + 8 + 25 + 6;

        fn reads_back_or_is_refused(bytes: &[u8]) -> Result<(), TestCaseError> {
            if let Ok(read) = decode(bytes) {
                prop_assert_eq!(decode(&encode(&read)), Ok(read), "what reads back writes and reads back alike");
            }
            Ok(())
        }

        proptest! {
            #[test]
            fn fuzz_snapshot_mutated_bytes(bytes in mutated_bytes(encode(&memory()))) {
                reads_back_or_is_refused(&bytes)?;
            }

            #[test]
            fn fuzz_snapshot_mutated_header(header in mutated_bytes(encode(&memory())[..HEADER].to_vec())) {
                let bytes = [header, encode(&memory())[HEADER..].to_vec()].concat();
                reads_back_or_is_refused(&bytes)?;
            }
        }
    }
}
