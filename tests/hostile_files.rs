//! Files a user points the rover at that lie about themselves: refused with a clear message, at a
//! bounded cost in memory.

mod support;

use std::path::Path;
use std::process::{Command, Stdio};

/// Most memory the simulator may use to refuse a hostile map, kilobytes.
const MAX_REFUSAL_RSS_KB: i64 = 50 * 1024;

/// Runs `command` to its end; its exit status, what it printed, and its peak resident memory, kB.
#[expect(clippy::zombie_processes, reason = "wait4 reaps the child, with its resource usage")]
fn run_measured(command: &mut Command) -> (i32, String, i64) {
    let child = command.stdout(Stdio::null()).stderr(Stdio::piped()).spawn().expect("start the command");
    let pid = child.id() as libc::pid_t;
    let mut stderr = child.stderr.expect("stderr");
    let printed = std::thread::spawn(move || {
        let mut text = String::new();
        std::io::Read::read_to_string(&mut stderr, &mut text).expect("read stderr");
        text
    });
    let mut status = 0;
    // SAFETY: `usage` is a zeroed plain C struct that wait4 fills; `pid` is our own child.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: as above; both pointers are valid for the call.
    let waited = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    assert_eq!(waited, pid, "wait4: {}", std::io::Error::last_os_error());
    (libc::WEXITSTATUS(status), printed.join().expect("stderr reader"), usage.ru_maxrss)
}

/// A PNG whose header claims `width` x `height` over the rows of a real image of `rows_bytes`.
fn lying_png(path: &Path, width: u32, height: u32, rows_bytes: usize) {
    let side = ((rows_bytes / 3) as f64).sqrt() as usize;
    let png = rover_imaging::encode_png(&rover_imaging::RgbImage::new(side, side)).expect("encode");
    std::fs::write(path, rover_fuzzing::mutation::with_png_size(&png, width, height)).expect("write the PNG");
}

#[test]
fn a_map_whose_header_claims_100000_pixels_a_side_is_refused_in_little_memory() {
    let dir = std::env::temp_dir().join(format!("rover-hostile-png-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let map = dir.join("huge.png");
    lying_png(&map, 100_000, 100_000, 300 << 20);
    let file_kb = std::fs::metadata(&map).unwrap().len() / 1024;
    let (code, printed, peak_kb) =
        run_measured(Command::new(support::rover()).args(["sim", "--port", "9", "--map"]).arg(&map));
    assert_ne!(code, 0, "a 100000x100000 map was accepted:\n{printed}");
    assert!(printed.contains("100000x100000") && printed.contains("huge.png"), "unclear refusal:\n{printed}");
    assert!(
        peak_kb < MAX_REFUSAL_RSS_KB,
        "refusing a {file_kb} kB file holding 300 MB of rows took {peak_kb} kB, over {MAX_REFUSAL_RSS_KB} kB"
    );
    std::fs::remove_dir_all(dir).unwrap();
}
