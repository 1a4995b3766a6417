//! The files of a bag folder, opened safely: paths from `metadata.yaml` confined to the folder,
//! only regular files opened (a FIFO or a device would block or never end), and `metadata.yaml`
//! replaced atomically so that a crash leaves the old or the new one, never half of one.

use std::fs::File;
use std::path::{Component, Path, PathBuf};

use rover_files::{FileError, FileKind};

use crate::BagError;

/// What a storage file path must be, for the errors.
const EXPECTED_PATH: &str = "expected a file name relative to the bag folder";

/// The path in `dir` of the storage file `relative`, as `metadata.yaml` lists it: a relative path
/// without `..`, with `/` or `\` (as on Windows) between its parts, naming a regular file that
/// stays inside `dir` when symbolic links are followed.
pub(crate) fn confined_storage_path(dir: &Path, relative: &str) -> Result<PathBuf, BagError> {
    let refused =
        |problem: String| BagError::StoragePath { dir: dir.to_path_buf(), path: relative.to_string(), problem };
    let path = dir.join(relative_parts(relative).map_err(refused)?);
    let kind = file_kind(&path).map_err(|e| refused(format!("cannot be read ({e}); expected a regular file")))?;
    if kind != FileKind::Regular {
        return Err(refused(format!("is {}; expected a regular file", kind.described())));
    }
    let (real_dir, real_path) = (canonical(dir)?, canonical(&path)?);
    if !real_path.starts_with(&real_dir) {
        return Err(refused(format!("leads to {} outside the bag folder; {EXPECTED_PATH}", real_path.display())));
    }
    Ok(path)
}

/// The parts of `relative` joined as a path of this system; an empty, absolute or drive path, or
/// one with a `..` part, is refused with the reason.
fn relative_parts(relative: &str) -> Result<PathBuf, String> {
    if relative.starts_with(['/', '\\']) || relative.as_bytes().get(1) == Some(&b':') {
        return Err(format!("is absolute; {EXPECTED_PATH}"));
    }
    let mut path = PathBuf::new();
    for part in relative.split(['/', '\\']) {
        match Path::new(part).components().next() {
            None | Some(Component::CurDir) => {}
            Some(Component::Normal(name)) => path.push(name),
            Some(Component::ParentDir) => return Err(format!("has a '..' part; {EXPECTED_PATH}")),
            Some(Component::RootDir | Component::Prefix(_)) => return Err(format!("is absolute; {EXPECTED_PATH}")),
        }
    }
    if path.as_os_str().is_empty() {
        return Err(format!("is empty; {EXPECTED_PATH}"));
    }
    Ok(path)
}

/// `path` with symbolic links resolved.
fn canonical(path: &Path) -> Result<PathBuf, BagError> {
    path.canonicalize().map_err(|e| BagError::io(path, e))
}

/// What `path` is, without opening it (opening a FIFO blocks).
fn file_kind(path: &Path) -> std::io::Result<FileKind> {
    Ok(FileKind::of(std::fs::metadata(path)?.file_type()))
}

/// Opens `path` for reading if it is a regular file no longer than `max_bytes`; `what` names the
/// file in the error ([`rover_files::open_regular`]).
pub(crate) fn open_regular(path: &Path, what: &str, max_bytes: u64) -> Result<(File, u64), BagError> {
    rover_files::open_regular(path, max_bytes).map_err(|e| bag_error(e, what))
}

/// Replaces `path` with `bytes` atomically ([`rover_files::replace_atomically`]).
pub(crate) fn replace_atomically(path: &Path, bytes: &[u8]) -> Result<(), BagError> {
    rover_files::replace_atomically(path, bytes).map_err(|e| bag_error(e, "a file"))
}

/// The bag's error for `error` on the file that `what` names.
fn bag_error(error: FileError, what: &str) -> BagError {
    match error {
        FileError::Io { path, error } => BagError::Io { path, source: error },
        FileError::NotRegular { path, kind } => BagError::Unsupported {
            path,
            what: format!("{what} that is {} (expected a regular file)", kind.described()),
        },
        FileError::TooLarge { path, bytes, max_bytes } => {
            BagError::Unsupported { path, what: format!("{what} of {bytes} bytes (at most {max_bytes} expected)") }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refusal(dir: &Path, relative: &str) -> String {
        confined_storage_path(dir, relative).unwrap_err().to_string()
    }

    #[test]
    fn relative_names_with_either_separator_stay_in_the_folder() {
        assert_eq!(relative_parts("run_0.mcap").unwrap(), Path::new("run_0.mcap"));
        assert_eq!(relative_parts("./sub\\run_0.mcap").unwrap(), Path::new("sub/run_0.mcap"));
        assert_eq!(relative_parts("sub//run_0.mcap").unwrap(), Path::new("sub/run_0.mcap"));
        for (bad, why) in [
            ("/etc/passwd", "is absolute"),
            ("\\\\server\\share\\x.mcap", "is absolute"),
            ("C:\\bags\\x.mcap", "is absolute"),
            ("../x", "'..'"),
            ("sub\\..\\..\\x", "'..'"),
            ("", "is empty"),
            ("./", "is empty"),
        ] {
            let problem = relative_parts(bad).unwrap_err();
            assert!(problem.contains(why) && problem.contains("relative to the bag folder"), "{bad}: {problem}");
        }
    }

    #[test]
    fn storage_paths_outside_the_folder_or_not_regular_files_are_refused_naming_them() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path();
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        std::fs::write(dir.join("sub/run_0.mcap"), b"x").unwrap();
        assert_eq!(confined_storage_path(dir, "sub\\run_0.mcap").unwrap(), dir.join("sub/run_0.mcap"));
        let absolute = refusal(dir, "/etc/passwd");
        assert!(absolute.contains("\"/etc/passwd\"") && absolute.contains("is absolute"), "{absolute}");
        assert!(refusal(dir, "../x").contains("'..'"));
        assert!(refusal(dir, "sub").contains("is a folder; expected a regular file"));
        assert!(refusal(dir, "missing.mcap").contains("cannot be read"));
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink("/etc/hostname", dir.join("outside.mcap")).unwrap();
            let outside = refusal(dir, "outside.mcap");
            assert!(outside.contains("outside the bag folder") && outside.contains("/etc/hostname"), "{outside}");
            std::os::unix::fs::symlink("sub/run_0.mcap", dir.join("inside.mcap")).unwrap();
            assert!(confined_storage_path(dir, "inside.mcap").is_ok());
            std::os::unix::fs::symlink("/dev/zero", dir.join("zero.mcap")).unwrap();
            assert!(refusal(dir, "zero.mcap").contains("is a device"));
            let fifo = dir.join("fifo.mcap");
            assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
            assert!(refusal(dir, "fifo.mcap").contains("is a FIFO; expected a regular file"));
            let opened = open_regular(&fifo, "a storage file", 10).unwrap_err().to_string();
            assert!(opened.contains("a FIFO (expected a regular file)"), "{opened}");
        }
    }

    #[test]
    fn a_replaced_file_holds_the_new_bytes_and_no_temporary_is_left() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path();
        let path = dir.join("metadata.yaml");
        replace_atomically(&path, b"old").unwrap();
        replace_atomically(&path, b"new").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
        assert_eq!(std::fs::read_dir(dir).unwrap().count(), 1);
        let too_long = open_regular(&path, "metadata", 2).unwrap_err().to_string();
        assert!(too_long.contains("3 bytes (at most 2 expected)"), "{too_long}");
    }
}
