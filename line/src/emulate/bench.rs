//! The emulated bench as a whole (`accelcal emulate`): one or more nodes, each its QEMU build with
//! its link on a pseudo-terminal, its own emulated front end on USART2 and QEMU's gdbstub, all
//! front ends reading one emulated head on TCP (one head state, one chamber). [`Bench::start`]
//! brings everything up and returns the addresses a user's commands talk to; [`Bench::run_until`]
//! keeps it running until a stop is requested or a QEMU ends; dropping the bench stops the
//! threads and kills every QEMU (their temporary directories go with them).
//!
//! Node `i` (0-based) reports the device id `contract::qemu_node_id(i)`: node 0 the fixed
//! `contract::QEMU_DEVICE_ID`, the others an id loaded at `contract::QEMU_ID_ADDR`.

use std::net::TcpListener;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use accelcal_shared::contract::qemu_node_id;
use accelcal_shared::slots::SlotImage;

use super::fault::{FaultCounter, HeadFault};
use super::frontend::{read_ctl, run_frontend, FeCounters, FrontEnd, PaceOptions};
use super::head::{bind_head, spawn_head_server, Clock, Head, Motion, SensorTemp};
use super::pty::Pty;
use super::zaber::{serve_zaber, spawn_zaber_pty, ZaberStage};
use crate::head::ZaberAxes;
use crate::node::qemu::{BlankSlot, Link, LinkChannel, Qemu, QemuOptions};
use crate::node::session::device_id_hex;
use accelcal_core::error::bad;
use accelcal_core::sim::Unit;

/// One emulated node on the head: its unit, its front end's noise, its record.
pub struct NodeOptions {
    /// The unit the node's front end reads.
    pub unit: Unit,
    /// Seed of the front end's noise.
    pub seed: u64,
    /// A record (file bytes) to load into slot 0 before boot, as if flashed earlier.
    pub record: Option<Vec<u8>>,
}

/// How to run the bench.
pub struct BenchOptions {
    /// The QEMU executable.
    pub qemu: PathBuf,
    /// The node's QEMU build.
    pub elf: PathBuf,
    /// The nodes on the head, at least one: node `i` reports the device id
    /// `contract::qemu_node_id(i)` (the first one `contract::QEMU_DEVICE_ID`).
    pub nodes: Vec<NodeOptions>,
    /// The head's motion.
    pub motion: Motion,
    /// The thermal chamber: the sensor's starting temperature (soaked there) and its lag.
    pub sensor: SensorTemp,
    /// The front end's pacing.
    pub pace: PaceOptions,
    /// Port of the first node's gdbstub (0: a free one); node `i`'s is this plus `i`.
    pub gdb_port: u16,
    /// Port of the head (0: a free one); a head on a pseudo-terminal has none.
    pub head_port: u16,
    /// The head's protocol and where it is served.
    pub head: HeadDialect,
    /// A fault the head injects once.
    pub head_fault: Option<HeadFault>,
    /// The first node's number among the line's emulated nodes, from 0: node `i` reports the
    /// device id `contract::qemu_node_id(first_node + i)`, so that two benches of one line
    /// report distinct devices.
    pub first_node: usize,
}

/// Which protocol the emulated head speaks, and where (`accelcal emulate --head`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum HeadDialect {
    /// The line protocol of `head::protocol` over TCP (`sim:HOST:PORT`).
    #[default]
    Sim,
    /// Zaber's ASCII protocol over TCP (`zaber:HOST:PORT`; `emulate::zaber`).
    Zaber,
    /// Zaber's ASCII protocol on a pseudo-terminal, as a serial chain (`zaber:/dev/pts/N`).
    ZaberPty,
}

/// Where to reach one emulated node.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct NodeEndpoints {
    /// The node's link, a pseudo-terminal.
    pub port: String,
    /// QEMU's gdbstub, `HOST:PORT`.
    pub gdb: String,
    /// The device id the node reports, hex.
    pub device_id: String,
}

/// What the bench's users connect to: the line `accelcal emulate` prints (its field names are an
/// interface). `port` and `gdb` are the first node's.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Endpoints {
    /// The first node's link, a pseudo-terminal.
    pub port: String,
    /// The first node's gdbstub, `HOST:PORT`.
    pub gdb: String,
    /// The head, the spec to pass to `--head`: `sim:HOST:PORT`, `zaber:HOST:PORT` or
    /// `zaber:/dev/pts/N`.
    pub head: String,
    /// Every node, in the order of the units.
    pub nodes: Vec<NodeEndpoints>,
}

/// One running node's front-end counters.
pub struct NodeCounters {
    /// Sets sent, sets skipped because QEMU fell behind.
    pub counters: Arc<FeCounters>,
    /// The rate the node asked its front end for, Hz (0 until it has).
    pub rate_hz: Arc<AtomicU32>,
}

/// A running bench.
pub struct Bench {
    /// Empty only while dropping.
    qemus: Vec<Qemu>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
    /// Where to connect.
    pub endpoints: Endpoints,
    /// Each node's front-end counters, in the order of the units.
    pub nodes: Vec<NodeCounters>,
}

/// Send buffer of the front end's socket, bytes (the kernel doubles it and applies its minimum).
const FE_SEND_BUFFER: usize = 2048;

/// A free TCP port on 127.0.0.1 (the port is released before QEMU binds it: a small race that
/// QEMU reports if lost).
fn free_port() -> std::io::Result<u16> {
    Ok(TcpListener::bind("127.0.0.1:0")?.local_addr()?.port())
}

impl Bench {
    /// Starts the head, then each node: QEMU and its front end reading the one head.
    pub fn start(mut opts: BenchOptions) -> anyhow::Result<Bench> {
        if opts.nodes.is_empty() {
            return Err(bad("the emulated bench needs at least one unit"));
        }
        for n in &opts.nodes {
            n.unit.check_triad()?;
        }
        opts.motion.check().map_err(|e| bad(format!("head motion: {e}")))?;
        let head_listener = match opts.head {
            HeadDialect::Sim | HeadDialect::Zaber => Some(bind_head(opts.head_port)?),
            HeadDialect::ZaberPty => None,
        };
        let stop = Arc::new(AtomicBool::new(false));
        let head = Arc::new(Head::with_chamber(Clock::start(), opts.motion, (0.0, 0.0), opts.sensor));
        let mut bench = Bench {
            qemus: Vec::new(),
            stop: stop.clone(),
            threads: Vec::new(),
            endpoints: Endpoints {
                port: String::new(),
                gdb: String::new(),
                head: String::new(),
                nodes: Vec::new(),
            },
            nodes: Vec::new(),
        };
        for (i, node) in std::mem::take(&mut opts.nodes).into_iter().enumerate() {
            let gdb_port = match opts.gdb_port {
                0 => free_port()?,
                p => p
                    .checked_add(i as u16)
                    .ok_or_else(|| bad(format!("--gdb-port {p}: no port for node {}", i + 1)))?,
            };
            let id = qemu_node_id(opts.first_node + i).ok_or_else(|| {
                bad(format!("the emulated line has at most 99 nodes, not {}", opts.first_node + i + 1))
            })?;
            let (qemu, ends, counters) =
                start_node(&opts, node, i, id, gdb_port, &head, &stop, &mut bench.threads)?;
            bench.qemus.push(qemu);
            bench.endpoints.nodes.push(ends);
            bench.nodes.push(counters);
        }
        bench.endpoints.head = match (opts.head, head_listener) {
            (HeadDialect::Sim, Some(listener)) => {
                let faults = Arc::new(FaultCounter::new(opts.head_fault));
                let (addr, thread) = spawn_head_server(listener, head, faults, stop)?;
                bench.threads.push(std::thread::spawn(move || {
                    let _ = thread.join();
                }));
                format!("sim:{addr}")
            }
            (HeadDialect::Zaber, Some(listener)) => {
                let addr = listener.local_addr()?;
                let stage = ZaberStage::new(head, ZaberAxes::default(), opts.head_fault);
                bench.threads.push(std::thread::spawn(move || {
                    let _ = serve_zaber(listener, &stage, &stop);
                }));
                format!("zaber:{addr}")
            }
            (_, _) => {
                let stage = Arc::new(ZaberStage::new(head, ZaberAxes::default(), opts.head_fault));
                let (path, threads) = spawn_zaber_pty(stage, &stop)
                    .map_err(|e| anyhow::anyhow!("opening the head's pseudo-terminal: {e}"))?;
                bench.threads.extend(threads);
                format!("zaber:{path}")
            }
        };
        let first = &bench.endpoints.nodes[0];
        bench.endpoints.port = first.port.clone();
        bench.endpoints.gdb = first.gdb.clone();
        Ok(bench)
    }

    /// Runs until `stop` is set (Ok) or a QEMU ends (the error carries its status and stderr,
    /// and names the node when there are several).
    pub fn run_until(&mut self, stop: &AtomicBool) -> anyhow::Result<()> {
        let several = self.qemus.len() > 1;
        loop {
            if stop.load(Ordering::Relaxed) {
                return Ok(());
            }
            for (i, q) in self.qemus.iter_mut().enumerate() {
                if let Some(e) = q.exited() {
                    let e = anyhow::Error::new(e);
                    return Err(if several {
                        e.context(format!("node {} of {}", i + 1, self.qemus.len()))
                    } else {
                        e
                    });
                }
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

/// Starts node `i`'s QEMU and its front end's two threads (into `threads`).
#[allow(clippy::too_many_arguments)]
fn start_node(
    opts: &BenchOptions,
    node: NodeOptions,
    i: usize,
    id: [u8; 12],
    gdb_port: u16,
    head: &Arc<Head>,
    stop: &Arc<AtomicBool>,
    threads: &mut Vec<JoinHandle<()>>,
) -> anyhow::Result<(Qemu, NodeEndpoints, NodeCounters)> {
    let mut fe = FrontEnd::new(node.unit, node.seed)?;
    let mut q = QemuOptions::new(&opts.elf);
    q.qemu = opts.qemu.clone();
    // USART1 on a socket, bridged to a terminal of this process's (see `pty`: QEMU's own pty
    // notices a program opening it only once a second).
    q.link = LinkChannel::Socket;
    q.frontend = true;
    q.gdb_port = Some(gdb_port);
    q.blank = BlankSlot::Erased;
    // Node 0 reports the fixed id without a block, as before several nodes existed.
    q.device_id = (opts.first_node + i > 0).then_some(id);
    q.spin_main_loop = std::env::var_os("ACCELCAL_EMULATE_SPIN").is_some();
    if let Some(rec) = &node.record {
        let image = SlotImage::build(rec, 1).map_err(|e| bad(format!("--record: {e}")))?;
        q.slots[0] = Some(image.to_vec());
    }
    let mut qemu = Qemu::start(&q)?;
    let port = match qemu.take_link() {
        Some(Link::Socket(sock)) => {
            let pty = Pty::open().map_err(|e| anyhow::anyhow!("opening the node's pseudo-terminal: {e}"))?;
            let port = pty.path.display().to_string();
            threads.extend(pty.bridge(sock, stop)?);
            port
        }
        _ => anyhow::bail!("QEMU did not connect the link's socket"),
    };
    let fe_sock = qemu.take_frontend().ok_or_else(|| anyhow::anyhow!("QEMU did not open the front end"))?;
    // A converter has no queue: sets the node has not taken must not pile up in the socket
    // (its default buffer holds seconds of sets, which would reach the node late, from a
    // head pose long past). With the smallest send buffer the writer blocks within a few
    // sets and the pacing loop skips what it cannot send, which the node counts as lost.
    socket2::SockRef::from(&fe_sock).set_send_buffer_size(FE_SEND_BUFFER)?;
    let rate_hz = Arc::new(AtomicU32::new(0));
    let counters = Arc::new(FeCounters::default());
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
    let ends = NodeEndpoints { port, gdb: format!("127.0.0.1:{gdb_port}"), device_id: device_id_hex(&id) };
    Ok((qemu, ends, NodeCounters { counters, rate_hz }))
}

impl Drop for Bench {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Kill QEMU first: a front end blocked writing to a halted guest then fails at once; the
        // other threads check the flag at least every 100 ms.
        self.qemus.clear();
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}
