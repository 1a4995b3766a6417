//! The mapping node's memory on disk: the map's evidence, home and the collected count, so that a
//! node restarted after a crash carries on where the last one stopped. A snapshot is one binary
//! file (little-endian, fixed layout, see [`encode`]) replaced atomically: written beside its final
//! name, flushed, then renamed over it, so a reader finds the old snapshot or the new one, never
//! half of one.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use rover_msgs::map_grid::CELLS;
use rover_msgs::tally::SampleTally;

use crate::map::{CLASSES, Evidence, WEIGHED};

/// The first bytes of a snapshot: the format and its version.
const MAGIC: &[u8; 8] = b"RVRMAP01";
/// The snapshot's file name in the state folder.
pub const FILE_NAME: &str = "mapping.snapshot";

/// Where the rover started: the frame, then world metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Home {
    /// Lock-step frame of the first telemetry.
    pub frame: u64,
    /// World x, metres.
    pub x_m: f64,
    /// World y, metres.
    pub y_m: f64,
}

/// Everything the mapping node must not lose across a restart.
#[derive(Debug, Clone, PartialEq)]
pub struct Memory {
    /// The map's evidence.
    pub evidence: Evidence,
    /// Where the rover started, once known.
    pub home: Option<Home>,
    /// The collected count and the last `samples_remaining`.
    pub tally: SampleTally,
}

/// A snapshot that cannot be read back.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SnapshotError {
    /// The bytes end before the layout does.
    #[error("the snapshot ends after {0} bytes, before its {1} field")]
    Truncated(usize, &'static str),
    /// Not a snapshot of this format.
    #[error("not a rover mapping snapshot (expected the bytes {MAGIC:?} first)")]
    NotASnapshot,
    /// Written for a map of another size.
    #[error("the snapshot holds {0} cells, this map has {CELLS}")]
    OtherSize(u64),
    /// A field holds a value no map can have.
    #[error("the snapshot's {0} holds {1}, expected {2}")]
    BadValue(&'static str, String, &'static str),
    /// Bytes beyond the layout.
    #[error("the snapshot has {0} bytes beyond its end")]
    TrailingBytes(usize),
}

/// The bytes of `memory`: the magic, the cell count (u64), home (flag u8, frame u64, x f64, y f64),
/// the tally (collected u32, flag u8, last remaining u8), then per class the hits (u16 per cell),
/// per weighed class the weights (f32 per cell) and the rock ranges (f32 per cell).
pub fn encode(memory: &Memory) -> Vec<u8> {
    let mut out = Vec::with_capacity(64 + CELLS * (2 * CLASSES + 4 * WEIGHED + 4));
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(CELLS as u64).to_le_bytes());
    let home = memory.home.unwrap_or(Home { frame: 0, x_m: 0.0, y_m: 0.0 });
    out.push(u8::from(memory.home.is_some()));
    out.extend_from_slice(&home.frame.to_le_bytes());
    out.extend_from_slice(&home.x_m.to_le_bytes());
    out.extend_from_slice(&home.y_m.to_le_bytes());
    out.extend_from_slice(&memory.tally.collected().to_le_bytes());
    out.push(u8::from(memory.tally.last_remaining().is_some()));
    out.push(memory.tally.last_remaining().unwrap_or(0));
    let evidence = &memory.evidence;
    evidence.hits.iter().flatten().for_each(|h| out.extend_from_slice(&h.to_le_bytes()));
    evidence.weight.iter().flatten().for_each(|w| out.extend_from_slice(&w.to_le_bytes()));
    evidence.rock_range_m.iter().for_each(|r| out.extend_from_slice(&r.to_le_bytes()));
    out
}

/// Reads `bytes` back into a memory, checking the layout and every value.
pub fn decode(bytes: &[u8]) -> Result<Memory, SnapshotError> {
    let mut reader = Reader { bytes, at: 0 };
    if reader.take::<8>("magic")? != *MAGIC {
        return Err(SnapshotError::NotASnapshot);
    }
    let cells = reader.u64("cell count")?;
    if cells != CELLS as u64 {
        return Err(SnapshotError::OtherSize(cells));
    }
    let has_home = reader.flag("home flag")?;
    let home = Home { frame: reader.u64("home frame")?, x_m: reader.f64("home x")?, y_m: reader.f64("home y")? };
    if has_home && !(home.x_m.is_finite() && home.y_m.is_finite()) {
        return Err(SnapshotError::BadValue("home", format!("({}, {})", home.x_m, home.y_m), "finite metres"));
    }
    let collected = u32::from_le_bytes(reader.take("collected count")?);
    let has_last = reader.flag("tally flag")?;
    let last_remaining = reader.take::<1>("samples remaining")?[0];
    let mut evidence = Evidence::empty();
    for class in &mut evidence.hits {
        for hits in class.iter_mut() {
            *hits = u16::from_le_bytes(reader.take("hits")?);
        }
    }
    for class in &mut evidence.weight {
        for weight in class.iter_mut() {
            *weight = reader.f32("weights")?;
            if !(weight.is_finite() && *weight >= 0.0) {
                return Err(SnapshotError::BadValue("weights", weight.to_string(), "finite and >= 0"));
            }
        }
    }
    for range_m in &mut evidence.rock_range_m {
        *range_m = reader.f32("rock ranges")?;
        if range_m.is_nan() || *range_m < 0.0 {
            return Err(SnapshotError::BadValue("rock ranges", range_m.to_string(), ">= 0 m or infinite"));
        }
    }
    if reader.at != bytes.len() {
        return Err(SnapshotError::TrailingBytes(bytes.len() - reader.at));
    }
    Ok(Memory {
        evidence,
        home: has_home.then_some(home),
        tally: SampleTally::resumed(collected, has_last.then_some(last_remaining)),
    })
}

/// Reads little-endian fields off a byte slice.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], SnapshotError> {
        let field_bytes =
            self.bytes.get(self.at..self.at + N).ok_or(SnapshotError::Truncated(self.bytes.len(), field))?;
        self.at += N;
        Ok(field_bytes.try_into().expect("N bytes"))
    }

    fn u64(&mut self, field: &'static str) -> Result<u64, SnapshotError> {
        self.take(field).map(u64::from_le_bytes)
    }

    fn f64(&mut self, field: &'static str) -> Result<f64, SnapshotError> {
        self.take(field).map(f64::from_le_bytes)
    }

    fn f32(&mut self, field: &'static str) -> Result<f32, SnapshotError> {
        self.take(field).map(f32::from_le_bytes)
    }

    fn flag(&mut self, field: &'static str) -> Result<bool, SnapshotError> {
        match self.take::<1>(field)?[0] {
            0 => Ok(false),
            1 => Ok(true),
            other => Err(SnapshotError::BadValue(field, other.to_string(), "0 or 1")),
        }
    }
}

/// The snapshot file of a state folder.
pub fn path_in(state_dir: &Path) -> PathBuf {
    state_dir.join(FILE_NAME)
}

/// Writes `memory` to `path` atomically: into `path` with `.tmp` appended, flushed to disk, then
/// renamed over `path`.
pub fn write(path: &Path, memory: &Memory) -> std::io::Result<()> {
    if let Some(folder) = path.parent() {
        std::fs::create_dir_all(folder)?;
    }
    let mut temporary = path.as_os_str().to_owned();
    temporary.push(".tmp");
    let temporary = PathBuf::from(temporary);
    let mut file = std::fs::File::create(&temporary)?;
    file.write_all(&encode(memory))?;
    file.sync_all()?;
    std::fs::rename(&temporary, path)
}

/// The memory in the snapshot at `path`; `Ok(None)` when there is no snapshot yet.
pub fn read(path: &Path) -> anyhow::Result<Option<Memory>> {
    match std::fs::read(path) {
        Ok(bytes) => Ok(Some(decode(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(anyhow::anyhow!("cannot read {}: {e}", path.display())),
    }
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
        }
    }

    #[test]
    fn a_snapshot_reads_back_as_written() {
        let memory = memory();
        assert_eq!(decode(&encode(&memory)), Ok(memory.clone()));
        let fresh = Memory { evidence: Evidence::empty(), home: None, tally: SampleTally::default() };
        assert_eq!(decode(&encode(&fresh)), Ok(fresh));
    }

    #[test]
    fn damaged_snapshots_are_refused_with_the_field_named() {
        let bytes = encode(&memory());
        assert_eq!(decode(&bytes[..bytes.len() - 1]), Err(SnapshotError::Truncated(bytes.len() - 1, "rock ranges")));
        assert_eq!(decode(&bytes[..20]), Err(SnapshotError::Truncated(20, "home frame")));
        assert_eq!(decode(b"GIF89a.."), Err(SnapshotError::NotASnapshot));
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

    #[test]
    fn writing_replaces_the_snapshot_whole() {
        let folder = std::env::temp_dir().join(format!("rover-snapshot-test-{}", std::process::id()));
        let path = path_in(&folder);
        assert_eq!(read(&path).unwrap(), None, "no snapshot yet");
        let mut memory = memory();
        write(&path, &memory).unwrap();
        memory.tally = SampleTally::resumed(3, Some(3));
        write(&path, &memory).unwrap();
        assert_eq!(read(&path).unwrap(), Some(memory));
        std::fs::write(&path, b"RVRMAP01").unwrap();
        let error = read(&path).unwrap_err().to_string();
        assert!(error.contains("mapping.snapshot") && error.contains("cell count"), "{error}");
        std::fs::remove_dir_all(&folder).unwrap();
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
