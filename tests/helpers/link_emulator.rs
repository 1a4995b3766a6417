//! `link_emulator`: joins two network namespaces by an impaired link, for kernels without `netem`.
//! It opens a TUN device in each namespace and forwards every packet (multicast included, for DDS
//! discovery) from one to the other with the delay, jitter and loss asked for ([`rover::processes::link`]).
//! `tools/two-hosts` starts it and gives the devices their addresses and routes.

use std::fs::File;
use std::io::{Read, Write};
use std::os::fd::AsRawFd;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context;
use clap::Parser;
use rover::processes::link::{Impairment, Link, LinkCounts, Way};
use rover_runtime::{Shutdown, logging};

/// Largest packet a TUN device hands over (its MTU is 1500; this leaves room).
const MAX_PACKET_BYTES: usize = 65_536;
/// How often the counts are logged.
const REPORT_PERIOD: Duration = Duration::from_secs(10);

/// Joins two network namespaces by an impaired link of two TUN devices.
#[derive(Debug, Parser)]
#[command(name = "link_emulator", version)]
struct Args {
    /// Network namespace of one end, e.g. /run/netns/rover.
    #[arg(long, value_name = "PATH")]
    netns_a: PathBuf,
    /// Network namespace of the other end.
    #[arg(long, value_name = "PATH")]
    netns_b: PathBuf,
    /// Name of the TUN device in each namespace.
    #[arg(long, value_name = "NAME", default_value = "link0")]
    device: String,
    /// Mean one-way delay, milliseconds.
    #[arg(long, value_name = "MS", default_value_t = 0.0)]
    delay_ms: f64,
    /// Each packet's delay varies uniformly by up to this much either way, milliseconds.
    #[arg(long, value_name = "MS", default_value_t = 0.0)]
    jitter_ms: f64,
    /// Share of packets lost in each direction, percent.
    #[arg(long, value_name = "PCT", default_value_t = 0.0)]
    loss_pct: f64,
    /// Cut the link once this many packets have entered it, both ways together: from then on
    /// every packet is lost.
    #[arg(long, value_name = "PACKETS")]
    cut_after_packets: Option<u64>,
    /// Seed of the delays and losses.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

impl Args {
    fn impairment(&self) -> anyhow::Result<Impairment> {
        let millis = |name: &str, value: f64| {
            anyhow::ensure!(
                value.is_finite() && (0.0..=10_000.0).contains(&value),
                "--{name} {value}: expected 0 to 10000 ms"
            );
            Ok(Duration::from_secs_f64(value / 1000.0))
        };
        anyhow::ensure!(
            self.loss_pct.is_finite() && (0.0..=100.0).contains(&self.loss_pct),
            "--loss-pct {}: expected 0 to 100",
            self.loss_pct
        );
        Ok(Impairment {
            delay: millis("delay-ms", self.delay_ms)?,
            jitter: millis("jitter-ms", self.jitter_ms)?,
            loss_pct: self.loss_pct,
            cut_after_packets: self.cut_after_packets,
        })
    }
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    logging::init(&rover_runtime::ros_args::LogArgs::default());
    let impairment = args.impairment()?;
    let a = open_tun_in(&args.netns_a, &args.device)?;
    let b = open_tun_in(&args.netns_b, &args.device)?;
    let link = Arc::new(Mutex::new(Link::new(impairment, args.seed)));
    forward(Way::AToB, a.try_clone()?, b.try_clone()?, link.clone());
    forward(Way::BToA, b, a, link.clone());
    tracing::info!(
        "link up: {} in {} <-> {} in {}; delay {} ms, jitter {} ms, loss {} %",
        args.device,
        args.netns_a.display(),
        args.device,
        args.netns_b.display(),
        args.delay_ms,
        args.jitter_ms,
        args.loss_pct
    );
    tokio::runtime::Builder::new_current_thread().enable_all().build()?.block_on(async {
        let shutdown = Shutdown::on_signals();
        let mut report = tokio::time::interval(REPORT_PERIOD);
        report.tick().await;
        loop {
            tokio::select! {
                () = shutdown.wait() => break,
                _ = report.tick() => log_counts(&link),
            }
        }
    });
    log_counts(&link);
    Ok(())
}

fn log_counts(link: &Mutex<Link>) {
    let line = |way: Way| {
        let counts: LinkCounts = link.lock().map(|l| l.counts(way)).unwrap_or_default();
        format!("{} packets ({} lost), {:.1} MB", counts.packets, counts.lost, counts.bytes as f64 / 1e6)
    };
    tracing::info!("{} {}; {} {}", label(Way::AToB), line(Way::AToB), label(Way::BToA), line(Way::BToA));
}

/// How the log names `way`.
fn label(way: Way) -> &'static str {
    match way {
        Way::AToB => "a->b",
        Way::BToA => "b->a",
    }
}

/// Opens a TUN device called `name` inside the network namespace at `netns` (from a thread of its
/// own that enters the namespace, so this process stays where it is).
fn open_tun_in(netns: &Path, name: &str) -> anyhow::Result<File> {
    anyhow::ensure!(
        !name.is_empty() && name.len() < libc::IFNAMSIZ && name.bytes().all(|c| c.is_ascii_alphanumeric() || c == b'_'),
        "--device {name:?}: expected 1 to {} letters, digits or _",
        libc::IFNAMSIZ - 1
    );
    let namespace =
        File::open(netns).with_context(|| format!("cannot open the network namespace {}", netns.display()))?;
    let name = name.to_string();
    std::thread::spawn(move || {
        // SAFETY: setns only changes the network namespace of this thread, with a valid descriptor.
        if unsafe { libc::setns(namespace.as_raw_fd(), libc::CLONE_NEWNET) } != 0 {
            return Err(std::io::Error::last_os_error()).context("cannot enter the network namespace (root needed)");
        }
        let tun = File::options().read(true).write(true).open("/dev/net/tun").context("cannot open /dev/net/tun")?;
        // SAFETY: ifreq is plain old data; all zeros is a valid value.
        let mut request: libc::ifreq = unsafe { std::mem::zeroed() };
        for (slot, byte) in request.ifr_name.iter_mut().zip(name.bytes()) {
            *slot = byte as libc::c_char;
        }
        request.ifr_ifru.ifru_flags = (libc::IFF_TUN | libc::IFF_NO_PI) as libc::c_short;
        // SAFETY: TUNSETIFF reads (and writes back) one ifreq that lives for the whole call.
        if unsafe { libc::ioctl(tun.as_raw_fd(), libc::TUNSETIFF, &mut request) } != 0 {
            return Err(std::io::Error::last_os_error())
                .with_context(|| format!("cannot create the TUN device {name}"));
        }
        Ok(tun)
    })
    .join()
    .map_err(|_| anyhow::anyhow!("the thread opening the TUN device panicked"))?
}

/// Forwards packets read from `from` to `to` going `way` through `link`, on two threads: one
/// reads and decides each packet's fate, one writes each packet when it is due.
fn forward(way: Way, mut from: File, mut to: File, link: Arc<Mutex<Link>>) {
    let label = label(way);
    let (due, delivery) = mpsc::channel::<(Instant, Vec<u8>)>();
    std::thread::spawn(move || {
        let mut buffer = vec![0u8; MAX_PACKET_BYTES];
        loop {
            let length = match from.read(&mut buffer) {
                Ok(length) => length,
                Err(e) => {
                    tracing::error!("{label}: cannot read a packet: {e}");
                    return;
                }
            };
            let departure = link.lock().expect("link lock").departure(way, Instant::now(), length);
            if let Some(at) = departure
                && due.send((at, buffer[..length].to_vec())).is_err()
            {
                return;
            }
        }
    });
    std::thread::spawn(move || {
        for (at, packet) in delivery {
            std::thread::sleep(at.saturating_duration_since(Instant::now()));
            if let Err(e) = to.write_all(&packet) {
                tracing::warn!("{label}: cannot deliver a packet of {} bytes: {e}", packet.len());
            }
        }
    });
}
