//! CPU time used by the processes of a run, read from `/proc`: how much of the machine the
//! simulator and each node took, per frame.

use std::collections::BTreeMap;
use std::time::Duration;

/// CPU time (user and system, all threads) that process `pid` has used so far; `None` when it
/// has gone or `/proc` cannot be read.
pub fn process_cpu_time(pid: u32) -> Option<Duration> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    cpu_time_from_stat(&stat, clock_ticks_per_s())
}

/// The clock ticks a second of `/proc`'s times.
fn clock_ticks_per_s() -> u64 {
    // SAFETY: sysconf only reads a system constant.
    let ticks = unsafe { libc::sysconf(libc::_SC_CLK_TCK) };
    u64::try_from(ticks).ok().filter(|&t| t > 0).unwrap_or(100)
}

/// User plus system time of a `/proc/PID/stat` line (fields 14 and 15, in clock ticks). The
/// process name, field 2, is in parentheses and may itself hold spaces and parentheses, so the
/// fields are counted from the last `)` on.
fn cpu_time_from_stat(stat: &str, ticks_per_s: u64) -> Option<Duration> {
    let after_name = &stat[stat.rfind(')')? + 1..];
    let mut fields = after_name.split_whitespace().skip(11);
    let user: u64 = fields.next()?.parse().ok()?;
    let system: u64 = fields.next()?.parse().ok()?;
    Some(Duration::from_secs_f64((user + system) as f64 / ticks_per_s as f64))
}

/// Measures the CPU time of named processes from a start on.
#[derive(Debug, Clone)]
pub struct CpuMeter {
    /// Each process's CPU time at the start, by pid.
    at_start: BTreeMap<u32, Duration>,
}

impl CpuMeter {
    /// Starts measuring the processes `(name, pid)`.
    pub fn start<'a>(processes: impl IntoIterator<Item = (&'a str, u32)>) -> Self {
        let at_start = processes.into_iter().filter_map(|(_, pid)| Some((pid, process_cpu_time(pid)?))).collect();
        CpuMeter { at_start }
    }

    /// The CPU time the processes `(name, pid)` used since the start, by name; a process started
    /// since (a node started again) counts from its own start, one that has gone is left out.
    pub fn used<'a>(&self, processes: impl IntoIterator<Item = (&'a str, u32)>) -> BTreeMap<String, Duration> {
        processes
            .into_iter()
            .filter_map(|(name, pid)| {
                let now = process_cpu_time(pid)?;
                let start = self.at_start.get(&pid).copied().unwrap_or_default();
                Some((name.to_string(), now.saturating_sub(start)))
            })
            .collect()
    }
}

/// CPU milliseconds a frame, by process, of `frames` frames that used `used`.
pub fn ms_per_frame(used: &BTreeMap<String, Duration>, frames: u64) -> BTreeMap<String, f64> {
    used.iter().map(|(name, time)| (name.clone(), time.as_secs_f64() * 1000.0 / frames.max(1) as f64)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn user_and_system_ticks_are_read_after_a_name_with_spaces_and_parentheses() {
        let stat = "4242 (rover (a) b) S 1 4242 4242 0 -1 4194560 2000 0 0 0 250 50 0 0 20 0 9 0 1000 0 0";
        assert_eq!(cpu_time_from_stat(stat, 100), Some(Duration::from_secs(3)));
        assert_eq!(cpu_time_from_stat("4242 (rover) S 1 2", 100), None, "too few fields");
        assert_eq!(cpu_time_from_stat("no parentheses", 100), None);
    }

    #[test]
    fn this_process_is_measured_and_a_busy_loop_shows() {
        let me = std::process::id();
        let meter = CpuMeter::start([("me", me)]);
        let started = std::time::Instant::now();
        let mut x = 0u64;
        while started.elapsed() < Duration::from_millis(300) {
            x = std::hint::black_box(x.wrapping_mul(31).wrapping_add(7));
        }
        let used = meter.used([("me", me), ("gone", u32::MAX)]);
        assert_eq!(used.keys().collect::<Vec<_>>(), ["me"], "a process that is not there is left out");
        assert!(used["me"] >= Duration::from_millis(100), "{used:?}");
        let per_frame = ms_per_frame(&used, 10);
        assert!((per_frame["me"] - used["me"].as_secs_f64() * 100.0).abs() < 1e-9);
    }
}
