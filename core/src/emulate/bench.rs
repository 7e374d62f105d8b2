//! The emulated bench as a whole (`accelcal emulate`): the node's QEMU build with its link on a
//! pseudo-terminal, the emulated front end on USART2, the emulated head on TCP, and QEMU's
//! gdbstub. [`Bench::start`] brings everything up and returns the three addresses a user's
//! commands talk to; [`Bench::run_until`] keeps it running until a stop is requested or QEMU
//! ends; dropping the bench stops the threads and kills QEMU (its temporary directory goes with
//! it).

use std::net::TcpListener;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use accelcal_shared::slots::SlotImage;

use super::frontend::{read_ctl, run_frontend, FeCounters, FrontEnd, PaceOptions};
use super::head::{bind_head, spawn_head_server, Clock, Head, Motion, SensorTemp};
use crate::error::bad;
use crate::node::qemu::{BlankSlot, Link, LinkChannel, Qemu, QemuOptions};
use crate::sim::Unit;

/// How to run the bench.
pub struct BenchOptions {
    /// The QEMU executable.
    pub qemu: PathBuf,
    /// The node's QEMU build.
    pub elf: PathBuf,
    /// The unit on the head.
    pub unit: Unit,
    /// Seed of the front end's noise.
    pub seed: u64,
    /// A record (file bytes) to load into slot 0 before boot, as if flashed earlier.
    pub record: Option<Vec<u8>>,
    /// The head's motion.
    pub motion: Motion,
    /// The thermal chamber: the sensor's starting temperature (soaked there) and its lag.
    pub sensor: SensorTemp,
    /// The front end's pacing.
    pub pace: PaceOptions,
    /// Port of the gdbstub (0: a free one).
    pub gdb_port: u16,
    /// Port of the head (0: a free one).
    pub head_port: u16,
}

/// What the bench's users connect to: the line `accelcal emulate` prints.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Endpoints {
    /// The node's link, a pseudo-terminal.
    pub port: String,
    /// QEMU's gdbstub, `HOST:PORT`.
    pub gdb: String,
    /// The head, `sim:HOST:PORT`.
    pub head: String,
}

/// A running bench.
pub struct Bench {
    /// `None` only while dropping.
    qemu: Option<Qemu>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
    /// Where to connect.
    pub endpoints: Endpoints,
    /// The front end's counters (sets sent, sets skipped because QEMU fell behind).
    pub counters: Arc<FeCounters>,
    /// The rate the node asked the front end for, Hz (0 until it has).
    pub rate_hz: Arc<AtomicU32>,
}

/// Send buffer of the front end's socket, bytes (the kernel doubles it and applies its minimum).
const FE_SEND_BUFFER: usize = 2048;

/// A free TCP port on 127.0.0.1 (the port is released before QEMU binds it: a small race that
/// QEMU reports if lost).
fn free_port() -> std::io::Result<u16> {
    Ok(TcpListener::bind("127.0.0.1:0")?.local_addr()?.port())
}

impl Bench {
    /// Starts QEMU, the front end and the head.
    pub fn start(opts: BenchOptions) -> anyhow::Result<Bench> {
        opts.unit.check_triad()?;
        opts.motion.check().map_err(|e| bad(format!("head motion: {e}")))?;
        let mut fe = FrontEnd::new(opts.unit, opts.seed)?;
        let gdb_port = if opts.gdb_port == 0 { free_port()? } else { opts.gdb_port };
        let head_listener = bind_head(opts.head_port)?;
        let mut q = QemuOptions::new(&opts.elf);
        q.qemu = opts.qemu.clone();
        q.link = LinkChannel::Pty;
        q.frontend = true;
        q.gdb_port = Some(gdb_port);
        q.blank = BlankSlot::Erased;
        q.spin_main_loop = std::env::var_os("ACCELCAL_EMULATE_SPIN").is_some();
        if let Some(rec) = &opts.record {
            let image = SlotImage::build(rec, 1).map_err(|e| bad(format!("--record: {e}")))?;
            q.slots[0] = Some(image.to_vec());
        }
        let mut qemu = Qemu::start(&q)?;
        let port = match qemu.take_link() {
            Some(Link::Pty(p)) => p.display().to_string(),
            _ => anyhow::bail!("QEMU did not give the link a pseudo-terminal"),
        };
        let fe_sock =
            qemu.take_frontend().ok_or_else(|| anyhow::anyhow!("QEMU did not open the front end"))?;
        // A converter has no queue: sets the node has not taken must not pile up in the socket
        // (its default buffer holds seconds of sets, which would reach the node late, from a
        // head pose long past). With the smallest send buffer the writer blocks within a few
        // sets and the pacing loop skips what it cannot send, which the node counts as lost.
        socket2::SockRef::from(&fe_sock).set_send_buffer_size(FE_SEND_BUFFER)?;
        let stop = Arc::new(AtomicBool::new(false));
        let head = Arc::new(Head::with_chamber(Clock::start(), opts.motion, (0.0, 0.0), opts.sensor));
        let (head_addr, head_thread) = spawn_head_server(head_listener, head.clone(), stop.clone())?;
        let rate_hz = Arc::new(AtomicU32::new(0));
        let counters = Arc::new(FeCounters::default());
        let mut threads = Vec::new();
        {
            let rx = fe_sock.try_clone()?;
            rx.set_read_timeout(Some(Duration::from_millis(100)))?;
            let (rate, stop) = (rate_hz.clone(), stop.clone());
            threads.push(std::thread::spawn(move || {
                let _ = read_ctl(rx, &rate, &stop);
            }));
        }
        {
            let (rate, stop, counters, head, pace) =
                (rate_hz.clone(), stop.clone(), counters.clone(), head.clone(), opts.pace);
            threads.push(std::thread::spawn(move || {
                let _ = run_frontend(&mut fe, &head, &rate, fe_sock, &stop, &pace, &counters);
            }));
        }
        threads.push(std::thread::spawn(move || {
            let _ = head_thread.join();
        }));
        let endpoints =
            Endpoints { port, gdb: format!("127.0.0.1:{gdb_port}"), head: format!("sim:{head_addr}") };
        Ok(Bench { qemu: Some(qemu), stop, threads, endpoints, counters, rate_hz })
    }

    /// Runs until `stop` is set (Ok) or QEMU ends (the error carries its status and stderr).
    pub fn run_until(&mut self, stop: &AtomicBool) -> anyhow::Result<()> {
        loop {
            if stop.load(Ordering::Relaxed) {
                return Ok(());
            }
            if let Some(e) = self.qemu.as_mut().and_then(Qemu::exited) {
                return Err(e.into());
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

impl Drop for Bench {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Kill QEMU first: a front end blocked writing to a halted guest then fails at once; the
        // other threads check the flag at least every 100 ms.
        drop(self.qemu.take());
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}
