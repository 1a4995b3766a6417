//! Files read and written safely, as every crate that takes a path from a user or a peer needs
//! them: only regular files are opened (a FIFO or a device would block or never end), a read is
//! bounded by a size given by the caller, and a replaced file holds the old or the new bytes
//! whole after a crash or power loss.

use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// Why a file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    /// The system refused.
    #[error("{}: {error}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the system said.
        error: std::io::Error,
    },
    /// The path names something other than a regular file.
    #[error("{} is {}; expected a regular file", path.display(), kind.described())]
    NotRegular {
        /// The file.
        path: PathBuf,
        /// What it is.
        kind: FileKind,
    },
    /// The file is larger than the reader takes.
    #[error("{} holds {bytes} bytes; at most {max_bytes} expected", path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size.
        bytes: u64,
        /// The most the reader takes.
        max_bytes: u64,
    },
}

impl FileError {
    fn io(path: &Path, error: std::io::Error) -> Self {
        FileError::Io { path: path.to_path_buf(), error }
    }
}

/// What a path names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileKind {
    /// A regular file.
    Regular,
    /// A folder.
    Directory,
    /// A named pipe.
    Fifo,
    /// A block or character device, or anything else.
    Device,
    /// A socket.
    Socket,
}

impl FileKind {
    /// The kind of `file_type`.
    pub fn of(file_type: std::fs::FileType) -> Self {
        #[cfg(unix)]
        {
            use std::os::unix::fs::FileTypeExt;
            if file_type.is_fifo() {
                return FileKind::Fifo;
            }
            if file_type.is_socket() {
                return FileKind::Socket;
            }
        }
        match (file_type.is_file(), file_type.is_dir()) {
            (true, _) => FileKind::Regular,
            (_, true) => FileKind::Directory,
            _ => FileKind::Device,
        }
    }

    /// What it is, for messages ("a FIFO").
    pub fn described(self) -> &'static str {
        match self {
            FileKind::Regular => "a regular file",
            FileKind::Directory => "a folder",
            FileKind::Fifo => "a FIFO",
            FileKind::Device => "a device",
            FileKind::Socket => "a socket",
        }
    }
}

/// Opens `path` for reading if it is a regular file of at most `max_bytes`; its size. The file is
/// opened without blocking, so a FIFO is refused, not waited on, even one put in place after a
/// check.
pub fn open_regular(path: &Path, max_bytes: u64) -> Result<(File, u64), FileError> {
    let mut options = OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::custom_flags(&mut options, libc::O_NONBLOCK);
    let file = options.open(path).map_err(|e| FileError::io(path, e))?;
    let metadata = file.metadata().map_err(|e| FileError::io(path, e))?;
    let kind = FileKind::of(metadata.file_type());
    if kind != FileKind::Regular {
        return Err(FileError::NotRegular { path: path.to_path_buf(), kind });
    }
    if metadata.len() > max_bytes {
        return Err(FileError::TooLarge { path: path.to_path_buf(), bytes: metadata.len(), max_bytes });
    }
    Ok((file, metadata.len()))
}

/// The bytes of the regular file `path`, refused when it holds more than `max_bytes`, even if it
/// grows while it is read: what a path names cannot make a reader allocate more than that.
pub fn read_at_most(path: &Path, max_bytes: u64) -> Result<Vec<u8>, FileError> {
    let (file, size) = open_regular(path, max_bytes)?;
    let mut bytes = Vec::with_capacity(usize::try_from(size).unwrap_or(0));
    file.take(max_bytes.saturating_add(1)).read_to_end(&mut bytes).map_err(|e| FileError::io(path, e))?;
    if bytes.len() as u64 > max_bytes {
        return Err(FileError::TooLarge { path: path.to_path_buf(), bytes: bytes.len() as u64, max_bytes });
    }
    Ok(bytes)
}

/// Replaces `path` with `bytes`, creating its folder if needed: written to a hidden temporary
/// file beside it, synced, renamed over it and the folder synced, so that after a crash or power
/// loss `path` holds the old or the new bytes whole.
pub fn replace_atomically(path: &Path, bytes: &[u8]) -> Result<(), FileError> {
    let folder = path.parent().filter(|folder| !folder.as_os_str().is_empty()).unwrap_or(Path::new("."));
    std::fs::create_dir_all(folder).map_err(|e| FileError::io(folder, e))?;
    let file_name = path.file_name().map(|name| name.to_string_lossy()).unwrap_or_default();
    let temporary = path.with_file_name(format!(".{file_name}.tmp"));
    let write = || -> std::io::Result<()> {
        let mut file = File::create(&temporary)?;
        file.write_all(bytes)?;
        file.sync_all()
    };
    write().map_err(|e| FileError::io(&temporary, e))?;
    std::fs::rename(&temporary, path).map_err(|e| FileError::io(path, e))?;
    #[cfg(unix)]
    File::open(folder).and_then(|folder| folder.sync_all()).map_err(|e| FileError::io(folder, e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_replaced_file_holds_the_new_bytes_in_a_new_folder_and_no_temporary_is_left() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path();
        let path = dir.join("state").join("decision.snapshot");
        replace_atomically(&path, b"old").unwrap();
        replace_atomically(&path, b"new").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
        assert_eq!(std::fs::read_dir(path.parent().unwrap()).unwrap().count(), 1);
    }

    #[test]
    fn a_read_takes_at_most_the_bound_and_names_the_file_over_it() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path();
        let path = dir.join("map.png");
        std::fs::write(&path, [7u8; 100]).unwrap();
        assert_eq!(read_at_most(&path, 100).unwrap().len(), 100);
        let error = read_at_most(&path, 99).unwrap_err().to_string();
        assert!(error.contains("map.png holds 100 bytes; at most 99 expected"), "{error}");
        let missing = read_at_most(&dir.join("none.png"), 99).unwrap_err().to_string();
        assert!(missing.contains("none.png"), "{missing}");
    }

    #[test]
    #[cfg(unix)]
    fn folders_devices_and_fifos_are_refused_without_blocking() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path();
        let fifo = dir.join("fifo.png");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        for (path, kind) in [(dir, "a folder"), (Path::new("/dev/zero"), "a device"), (&fifo, "a FIFO")] {
            let error = read_at_most(path, 10).unwrap_err().to_string();
            assert!(error.contains(&format!("is {kind}; expected a regular file")), "{error}");
        }
    }
}
