//! The decision node's memory on disk: what the exploration learnt, the rocks given up on, where
//! the mission stands and how far its time has got, so that a node restarted after a crash neither
//! explores again what it had seen nor chases what it had given up, and keeps its deadline (a
//! snapshot file of [`rover_runtime::snapshot`], layout in [`encode`]). Home and the collected count
//! come from the mapping node (`rover/map_stats`).

use rover_msgs::frames::MissionFrames;
use rover_msgs::map_grid::CELLS;
use rover_runtime::snapshot::{Fields, SnapshotError, Writer};

use crate::explore::ExplorerMemory;
use crate::machine::{Recollection, Stage};

/// The first bytes of a snapshot: the format and its version.
const MAGIC: &[u8; 8] = b"RVRDEC01";
/// The snapshot's file name in the state folder.
pub(crate) const FILE_NAME: &str = "decision.snapshot";
/// Most rocks a snapshot may list.
const MAX_ROCKS: u32 = 10_000;

/// What the decision node keeps in its snapshot.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Snapshot {
    /// The machine's recollection.
    pub recollection: Recollection,
    /// The last bridge frame and mission frame.
    pub mission_frames: MissionFrames,
}

/// The bytes of `snapshot`: the magic, the cell count (u64), the last frames (flag u8, bridge
/// frame u64, mission frame u64), the stage (u8: 0 exploring, 1 returning home, 2 done), plans
/// past obstacles (u8), then one byte (0 or 1) per cell for inspected, one per cell for explored,
/// and the ignored rocks (count u32, then x and y f64 each).
pub(crate) fn encode(snapshot: &Snapshot) -> Vec<u8> {
    let mut out = Writer::new(MAGIC);
    out.u64(CELLS as u64);
    let last = snapshot.mission_frames.last();
    out.flag(last.is_some());
    out.u64(last.map_or(0, |l| l.0));
    out.u64(last.map_or(0, |l| l.1));
    let recollection = &snapshot.recollection;
    out.u8(match recollection.stage {
        Stage::Exploring => 0,
        Stage::ReturningHome => 1,
        Stage::Done => 2,
    });
    let explorer = &recollection.explorer;
    out.flag(explorer.past_obstacles);
    explorer.inspected.iter().chain(&explorer.explored).for_each(|&cell| out.flag(cell));
    out.u32(recollection.ignored_rocks.len() as u32);
    recollection.ignored_rocks.iter().for_each(|&rock| out.place_m(rock));
    out.bytes
}

/// Reads `bytes` back into a snapshot, checking the layout and every value.
pub(crate) fn decode(bytes: &[u8]) -> Result<Snapshot, SnapshotError> {
    let mut fields = Fields::after_magic(bytes, MAGIC)?;
    fields.expect_u64("cell count", CELLS as u64)?;
    let has_frames = fields.flag("frames flag")?;
    let last = (fields.u64("bridge frame")?, fields.u64("mission frame")?);
    let mission_frames = MissionFrames::resumed(has_frames.then_some(last));
    let stage = match fields.u8("stage")? {
        0 => Stage::Exploring,
        1 => Stage::ReturningHome,
        2 => Stage::Done,
        other => return Err(SnapshotError::BadValue("stage", other.to_string(), "0, 1 or 2")),
    };
    let past_obstacles = fields.flag("past obstacles")?;
    let inspected = (0..CELLS).map(|_| fields.flag("inspected cells")).collect::<Result<_, _>>()?;
    let explored = (0..CELLS).map(|_| fields.flag("explored cells")).collect::<Result<_, _>>()?;
    let rocks = fields.u32("rock count")?;
    if rocks > MAX_ROCKS {
        return Err(SnapshotError::BadValue("rock count", rocks.to_string(), "at most 10000"));
    }
    let ignored_rocks = (0..rocks).map(|_| fields.place_m("rocks")).collect::<Result<_, _>>()?;
    fields.finish()?;
    let recollection =
        Recollection { explorer: ExplorerMemory { inspected, explored, past_obstacles }, ignored_rocks, stage };
    Ok(Snapshot { recollection, mission_frames })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn snapshot() -> Snapshot {
        let mut inspected = vec![false; CELLS];
        inspected[4321] = true;
        let mut explored = vec![false; CELLS];
        explored[CELLS - 1] = true;
        let recollection = Recollection {
            explorer: ExplorerMemory { inspected, explored, past_obstacles: true },
            ignored_rocks: vec![(101.5, 87.25), (12.0, 190.0)],
            stage: Stage::ReturningHome,
        };
        Snapshot { recollection, mission_frames: MissionFrames::resumed(Some((5000, 27000))) }
    }

    #[test]
    fn a_snapshot_reads_back_as_written() {
        let snapshot = snapshot();
        assert_eq!(decode(&encode(&snapshot)), Ok(snapshot));
    }

    #[test]
    fn damaged_snapshots_are_refused_with_the_field_named() {
        let bytes = encode(&snapshot());
        assert_eq!(decode(&bytes[..bytes.len() - 3]), Err(SnapshotError::Truncated(bytes.len() - 3, "rocks")));
        let mut bad_stage = bytes.clone();
        bad_stage[33] = 9;
        assert!(matches!(decode(&bad_stage), Err(SnapshotError::BadValue("stage", ..))));
        let mut nan_rock = bytes.clone();
        let last_rock = bytes.len() - 16;
        nan_rock[last_rock..last_rock + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        assert!(matches!(decode(&nan_rock), Err(SnapshotError::BadValue("rocks", ..))));
        let mut many_rocks = bytes;
        let count = 35 + 2 * CELLS;
        many_rocks[count..count + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(decode(&many_rocks), Err(SnapshotError::BadValue("rock count", ..))));
    }

    mod fuzz {
        use proptest::prelude::*;
        use rover_fuzzing::mutation::mutated_bytes;

        use super::*;

        proptest! {
            #[test]
            fn fuzz_decision_snapshot_mutated_bytes(bytes in mutated_bytes(encode(&snapshot()))) {
                if let Ok(read) = decode(&bytes) {
                    prop_assert_eq!(decode(&encode(&read)), Ok(read));
                }
            }
        }
    }
}
