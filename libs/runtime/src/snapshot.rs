//! Snapshot files: what a node must not lose across a restart, kept in a file of its state folder
//! (the `state_dir` parameter) that is replaced atomically: written beside its final name, then
//! renamed over it, so a reader finds the old snapshot or the new one, never part of one. A
//! snapshot is a fixed little-endian layout that starts with an 8-byte magic naming its format;
//! [`Fields`] reads one back and names the field that is missing or wrong.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rover_msgs::validate::MAX_POSITION_M;

/// A snapshot that cannot be read back.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SnapshotError {
    /// The bytes end before the layout does.
    #[error("the snapshot ends after {0} bytes, before its {1} field")]
    Truncated(usize, &'static str),
    /// Not a snapshot of the expected format.
    #[error("not a snapshot of this format (expected the bytes {0:?} first)")]
    NotASnapshot(&'static [u8; 8]),
    /// A field holds a value the node cannot have.
    #[error("the snapshot's {0} holds {1}, expected {2}")]
    BadValue(&'static str, String, &'static str),
    /// Bytes beyond the layout.
    #[error("the snapshot has {0} bytes beyond its end")]
    TrailingBytes(usize),
}

/// The snapshot file `name` of the state folder `state_dir`; `None` when the folder is empty
/// (no snapshots).
pub fn path_in(state_dir: &str, name: &str) -> Option<PathBuf> {
    (!state_dir.is_empty()).then(|| Path::new(state_dir).join(name))
}

/// The bytes of the snapshot at `path`, `None` when there is none yet; an unreadable file is an
/// error naming it.
pub fn read(path: &Path) -> anyhow::Result<Option<Vec<u8>>> {
    match std::fs::read(path) {
        Ok(bytes) => Ok(Some(bytes)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(anyhow::anyhow!("cannot read {}: {e}", path.display())),
    }
}

/// A node's snapshot file: where it is (if the node keeps one) and when it was last written.
#[derive(Debug)]
pub struct SnapshotFile {
    path: Option<PathBuf>,
    written_at: Option<Instant>,
}

impl SnapshotFile {
    /// The snapshot `name` in the state folder `state_dir` (none when `state_dir` is empty).
    pub fn new(state_dir: &str, name: &str) -> Self {
        SnapshotFile { path: path_in(state_dir, name), written_at: None }
    }

    /// The earlier node's snapshot, read with `decode`; `None` when there is no snapshot (or no
    /// state folder). A snapshot that cannot be read is logged and left alone: the next write
    /// replaces it.
    pub fn load<T>(&self, decode: impl FnOnce(&[u8]) -> Result<T, SnapshotError>) -> Option<T> {
        let path = self.path.as_ref()?;
        match read(path) {
            Ok(Some(bytes)) => match decode(&bytes) {
                Ok(loaded) => Some(loaded),
                Err(e) => {
                    tracing::warn!("cannot restore from {}: {e}; starting afresh", path.display());
                    None
                }
            },
            Ok(None) => {
                tracing::info!("no snapshot at {} yet: starting afresh", path.display());
                None
            }
            Err(e) => {
                tracing::warn!("{e:#}; starting afresh");
                None
            }
        }
    }

    /// Whether a write is due: the node keeps a snapshot and `every` has passed since the last.
    pub fn due(&self, every: Duration) -> bool {
        self.path.is_some() && self.written_at.is_none_or(|at| at.elapsed() >= every)
    }

    /// Writes `bytes` as the snapshot (atomically, see [`rover_files::replace_atomically`]); a failure is logged.
    pub fn save(&mut self, bytes: &[u8]) {
        let Some(path) = &self.path else { return };
        self.written_at = Some(Instant::now());
        if let Err(e) = rover_files::replace_atomically(path, bytes) {
            tracing::warn!("cannot write the snapshot {}: {e}", path.display());
        }
    }

    /// Where the snapshot is, if the node keeps one.
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }
}

/// Appends little-endian fields to a snapshot.
#[derive(Debug, Default)]
pub struct Writer {
    /// The bytes so far.
    pub bytes: Vec<u8>,
}

impl Writer {
    /// A snapshot that starts with `magic`.
    pub fn new(magic: &[u8; 8]) -> Self {
        Writer { bytes: magic.to_vec() }
    }

    /// Appends `value`.
    pub fn u64(&mut self, value: u64) {
        self.bytes.extend_from_slice(&value.to_le_bytes());
    }

    /// Appends `value`.
    pub fn u32(&mut self, value: u32) {
        self.bytes.extend_from_slice(&value.to_le_bytes());
    }

    /// Appends `value`.
    pub fn u16(&mut self, value: u16) {
        self.bytes.extend_from_slice(&value.to_le_bytes());
    }

    /// Appends `value`.
    pub fn u8(&mut self, value: u8) {
        self.bytes.push(value);
    }

    /// Appends `value`.
    pub fn f64(&mut self, value: f64) {
        self.bytes.extend_from_slice(&value.to_le_bytes());
    }

    /// Appends `value`.
    pub fn f32(&mut self, value: f32) {
        self.bytes.extend_from_slice(&value.to_le_bytes());
    }

    /// Appends `value` as one byte, 0 or 1.
    pub fn flag(&mut self, value: bool) {
        self.bytes.push(u8::from(value));
    }

    /// Appends a place on the map, x then y, metres.
    pub fn place_m(&mut self, (x_m, y_m): (f64, f64)) {
        self.f64(x_m);
        self.f64(y_m);
    }
}

/// Reads little-endian fields off a snapshot, naming the field that is missing or wrong.
#[derive(Debug)]
pub struct Fields<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Fields<'a> {
    /// The fields of `bytes`, which must start with `magic`.
    pub fn after_magic(bytes: &'a [u8], magic: &'static [u8; 8]) -> Result<Self, SnapshotError> {
        if bytes.get(..8) != Some(magic.as_slice()) {
            return Err(SnapshotError::NotASnapshot(magic));
        }
        Ok(Fields { bytes, at: 8 })
    }

    /// The next `N` bytes.
    pub fn take<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], SnapshotError> {
        let end = self.at.checked_add(N).filter(|&end| end <= self.bytes.len());
        let taken =
            end.map(|end| &self.bytes[self.at..end]).ok_or(SnapshotError::Truncated(self.bytes.len(), field))?;
        self.at += N;
        Ok(taken.try_into().expect("N bytes"))
    }

    /// The next u64.
    pub fn u64(&mut self, field: &'static str) -> Result<u64, SnapshotError> {
        self.take(field).map(u64::from_le_bytes)
    }

    /// The next u32.
    pub fn u32(&mut self, field: &'static str) -> Result<u32, SnapshotError> {
        self.take(field).map(u32::from_le_bytes)
    }

    /// The next u16.
    pub fn u16(&mut self, field: &'static str) -> Result<u16, SnapshotError> {
        self.take(field).map(u16::from_le_bytes)
    }

    /// The next byte.
    pub fn u8(&mut self, field: &'static str) -> Result<u8, SnapshotError> {
        self.take::<1>(field).map(|[byte]| byte)
    }

    /// The next f64.
    pub fn f64(&mut self, field: &'static str) -> Result<f64, SnapshotError> {
        self.take(field).map(f64::from_le_bytes)
    }

    /// The next f32.
    pub fn f32(&mut self, field: &'static str) -> Result<f32, SnapshotError> {
        self.take(field).map(f32::from_le_bytes)
    }

    /// The next byte as a flag: 0 or 1, anything else is refused.
    pub fn flag(&mut self, field: &'static str) -> Result<bool, SnapshotError> {
        match self.u8(field)? {
            0 => Ok(false),
            1 => Ok(true),
            other => Err(SnapshotError::BadValue(field, other.to_string(), "0 or 1")),
        }
    }

    /// The next place on the map, x then y: finite metres within [`MAX_POSITION_M`] of the origin.
    pub fn place_m(&mut self, field: &'static str) -> Result<(f64, f64), SnapshotError> {
        let place = (self.f64(field)?, self.f64(field)?);
        if place.0.abs() <= MAX_POSITION_M && place.1.abs() <= MAX_POSITION_M {
            Ok(place)
        } else {
            Err(SnapshotError::BadValue(field, format!("{place:?}"), "finite metres on the map"))
        }
    }

    /// The next u64, which must be `expected` (e.g. a grid's cell count).
    pub fn expect_u64(&mut self, field: &'static str, expected: u64) -> Result<(), SnapshotError> {
        let value = self.u64(field)?;
        if value == expected {
            Ok(())
        } else {
            Err(SnapshotError::BadValue(field, value.to_string(), "the grid of this node"))
        }
    }

    /// Ends the reading: no bytes may be left.
    pub fn finish(self) -> Result<(), SnapshotError> {
        match self.bytes.len() - self.at {
            0 => Ok(()),
            left => Err(SnapshotError::TrailingBytes(left)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MAGIC: &[u8; 8] = b"TESTSNAP";

    #[test]
    fn fields_read_back_and_name_what_is_missing() {
        let mut writer = Writer::new(MAGIC);
        writer.u64(7);
        writer.flag(true);
        writer.f32(0.5);
        let mut fields = Fields::after_magic(&writer.bytes, MAGIC).unwrap();
        assert_eq!(fields.u64("count"), Ok(7));
        assert_eq!(fields.flag("flag"), Ok(true));
        assert_eq!(fields.f32("weight"), Ok(0.5));
        assert_eq!(fields.u8("extra"), Err(SnapshotError::Truncated(21, "extra")));
        assert_eq!(Fields::after_magic(b"OTHERSNAP", MAGIC).unwrap_err(), SnapshotError::NotASnapshot(MAGIC));
        let mut bad_flag = Fields::after_magic(b"TESTSNAP\x02\x00", MAGIC).unwrap();
        assert!(matches!(bad_flag.flag("home flag"), Err(SnapshotError::BadValue("home flag", ..))));
        assert_eq!(bad_flag.finish(), Err(SnapshotError::TrailingBytes(1)));
    }

    #[test]
    fn a_snapshot_is_read_once_written_and_none_before() {
        let folder = std::env::temp_dir().join(format!("rover-snapshot-file-test-{}", std::process::id()));
        let path = path_in(folder.to_str().unwrap(), "node.snapshot").unwrap();
        assert_eq!(read(&path).unwrap(), None, "no snapshot yet");
        rover_files::replace_atomically(&path, b"second").unwrap();
        assert_eq!(read(&path).unwrap(), Some(b"second".to_vec()));
        assert_eq!(path_in("", "node.snapshot"), None);
        std::fs::remove_dir_all(&folder).unwrap();
    }
}
