//! The driver against the emulated stage (`crate::emulate::zaber`), in process over TCP and over
//! a pseudo-terminal: homing, moves, read-back, each injected fault, a stop mid-move.

use super::*;
use crate::emulate::fault::{FaultKind, HeadFault};
use crate::emulate::head::{bind_head, Clock, Head, Motion};
use crate::emulate::zaber::{serve_zaber, spawn_zaber_pty, ZaberStage};
use crate::head::settled;

struct Rig {
    head: Arc<Head>,
    stage: Arc<ZaberStage>,
    addr: String,
    stop: Arc<AtomicBool>,
    server: Option<std::thread::JoinHandle<()>>,
}

impl Rig {
    fn start(speed_deg_s: f64, fault: Option<HeadFault>) -> Rig {
        let head = Arc::new(Head::new(Clock::start(), Motion { speed_deg_s, overhead_s: 0.02 }, (0.0, 0.0)));
        let stage = Arc::new(ZaberStage::new(head.clone(), ZaberAxes::default(), fault));
        let listener = bind_head(0).unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let stop = Arc::new(AtomicBool::new(false));
        let (st, s) = (stage.clone(), stop.clone());
        let server = std::thread::spawn(move || {
            serve_zaber(listener, &st, &s).unwrap();
        });
        Rig { head, stage, addr, stop, server: Some(server) }
    }

    fn connect(&self, timeout: Duration, stop: Arc<AtomicBool>) -> ZaberHead {
        ZaberHead::connect(&ZaberPort::Tcp(self.addr.clone()), ZaberAxes::default(), timeout, stop).unwrap()
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(s) = self.server.take() {
            let _ = s.join();
        }
    }
}

fn target(alpha_deg: f64, beta_deg: f64) -> Target {
    Target { k: 0, n: 1, angles: Angles { alpha_deg, beta_deg }, expected_m_s2: [0.0; 3] }
}

const STEP: f64 = ZaberAxes::DEG_PER_STEP;

#[test]
fn homes_moves_and_reads_back_one_head_move_per_position() {
    let rig = Rig::start(900.0, None);
    let mut z = rig.connect(Duration::from_secs(5), Arc::new(AtomicBool::new(false)));
    let d = z.describe();
    assert!(
        d.starts_with(&format!("zaber:{} (alpha 1/1 device.id 0, beta 2/1 device.id 0", rig.addr)),
        "{d}"
    );
    // Not homed: a move is refused until `home`.
    let e = z.move_to(Angles { alpha_deg: 1.0, beta_deg: 0.0 }).unwrap_err().to_string();
    assert!(
        e.contains("alpha (device 1 axis 1) refused `move abs 4267`") && e.contains("WH (not homed)"),
        "{e}"
    );
    z.home().unwrap();
    for (k, (a, b)) in [(90.0, -45.0), (270.5, 60.0), (0.0, 0.0)].into_iter().enumerate() {
        let got = z.set(&target(a, b)).unwrap();
        assert!((got.alpha_deg - a).abs() <= STEP / 2.0 && (got.beta_deg - b).abs() <= STEP / 2.0, "{got:?}");
        assert_eq!(z.read_back().unwrap(), got);
        let p = rig.head.pose();
        assert!(p.moving.is_none() && (p.alpha_deg - a).abs() <= STEP, "{p:?}");
        assert_eq!(p.moves_completed, k + 1, "one head move per position");
    }
    // Homing again finds both axes homed: nothing moves.
    z.home().unwrap();
    assert_eq!(rig.head.pose().moves_completed, 3);
    z.stop().unwrap();
}

#[test]
fn each_injected_fault_is_an_error_naming_the_axis() {
    let alpha = "alpha (device 1 axis 1)";
    for kind in
        [FaultKind::Reject, FaultKind::NotHomed, FaultKind::Stall, FaultKind::Limit, FaultKind::Silent]
    {
        let rig = Rig::start(450.0, Some(HeadFault { kind, at_move: 2 }));
        let mut z = rig.connect(Duration::from_millis(700), Arc::new(AtomicBool::new(false)));
        z.home().unwrap();
        z.set(&target(10.0, 5.0)).unwrap();
        let e = z.set(&target(100.0, -60.0)).unwrap_err();
        let e = e.downcast::<HeadError>().unwrap();
        let msg = e.to_string();
        assert!(msg.starts_with(&format!("head zaber:{}: ", rig.addr)), "{msg}");
        match kind {
            FaultKind::Reject => {
                assert!(matches!(e, HeadError::Rejected { .. }), "{e:?}");
                assert!(msg.contains(&format!("{alpha} refused `move abs 426667`: @01 1 RJ")), "{msg}");
            }
            FaultKind::NotHomed => {
                assert!(matches!(e, HeadError::Rejected { .. }), "{e:?}");
                assert!(msg.contains(alpha) && msg.contains("WH (not homed)"), "{msg}");
            }
            FaultKind::Stall | FaultKind::Limit => {
                assert!(matches!(e, HeadError::Fault { .. }), "{e:?}");
                let flag = if kind == FaultKind::Stall {
                    "FS (stalled and stopped)"
                } else {
                    "WL (unexpected limit"
                };
                assert!(msg.contains(&format!("{alpha} reports a fault: {flag}")), "{msg}");
                // Stopped half-way, standing.
                let p = rig.head.pose();
                assert!(p.moving.is_none() && p.alpha_deg > 10.0 && p.alpha_deg < 100.0, "{p:?}");
            }
            FaultKind::Silent => {
                assert!(matches!(e, HeadError::Timeout { .. }), "{e:?}");
                assert!(msg.contains("no reply to `/1 1 move abs 426667; /2 1 move abs -256000`"), "{msg}");
            }
            FaultKind::Off(_) => unreachable!(),
        }
        // The same command again meets no fault; a fresh connection homes (clearing the
        // fault flags) and finishes.
        drop(z);
        let mut z = rig.connect(Duration::from_secs(5), Arc::new(AtomicBool::new(false)));
        z.home().unwrap();
        let got = z.set(&target(100.0, -60.0)).unwrap();
        assert!((got.alpha_deg - 100.0).abs() <= STEP, "{kind}: {got:?}");
    }
}

#[test]
fn a_head_that_lands_off_target_is_refused_with_both_angles() {
    let rig = Rig::start(900.0, Some(HeadFault { kind: FaultKind::Off(36.0), at_move: 1 }));
    let mut z = rig.connect(Duration::from_secs(5), Arc::new(AtomicBool::new(false)));
    z.home().unwrap();
    let t = target(90.0, 0.0);
    let got = z.set(&t).unwrap();
    assert!((got.alpha_deg - 90.01).abs() <= STEP, "{got:?}");
    let e = settled(&z.describe(), &t, got, 10.0).unwrap_err().to_string();
    assert!(e.contains("commanded alpha 90 deg") && e.contains("36.3 arcsec off"), "{e}");
}

#[test]
fn a_stop_mid_move_stops_both_axes_where_they_are() {
    let rig = Rig::start(30.0, None);
    let stop = Arc::new(AtomicBool::new(false));
    let mut z = rig.connect(Duration::from_secs(10), stop.clone());
    z.home().unwrap();
    let s = stop.clone();
    let t = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(500));
        s.store(true, Ordering::Relaxed);
    });
    let t0 = Instant::now();
    let got = z.set(&target(90.0, -90.0)).unwrap();
    t.join().unwrap();
    assert!(t0.elapsed() < Duration::from_secs(2), "{:?}", t0.elapsed());
    assert!(got.alpha_deg > 5.0 && got.alpha_deg < 45.0, "{got:?}");
    assert!((got.beta_deg + got.alpha_deg).abs() <= 2.0 * STEP, "both axes stopped together: {got:?}");
    let p = rig.head.pose();
    assert!(p.moving.is_none() && (p.alpha_deg - got.alpha_deg).abs() <= STEP, "{p:?}");
    // The stage answers IDLE at the stopped position.
    assert_eq!(rig.stage.answer(b"/1 1\n").unwrap(), "@01 1 OK IDLE -- 0\r\n");
    let pos = rig.stage.answer(b"/1 1 get pos\n").unwrap();
    assert_eq!(pos, format!("@01 1 OK IDLE -- {}\r\n", (got.alpha_deg / STEP).round() as i64));
}

#[test]
fn a_reply_from_another_axis_or_with_a_bad_checksum_is_refused() {
    for (reply, want) in [
        (&b"@02 1 OK IDLE -- 0\r\n"[..], "a reply from device 2 axis 1"),
        (b"@01 0 OK IDLE -- 0:00\r\n", "bad checksum"),
        (b"@01 0 OK IDLE -- \x1b[2J\r\n", r"not printable ASCII text"),
    ] {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let server = std::thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            let mut buf = [0u8; 64];
            let _ = s.read(&mut buf);
            s.write_all(b"#01 0 an info line to skip\r\n!01 1 IDLE --\r\n").unwrap();
            s.write_all(reply).unwrap();
            std::thread::sleep(Duration::from_millis(200));
        });
        let e = ZaberHead::connect(
            &ZaberPort::Tcp(addr),
            ZaberAxes::default(),
            Duration::from_secs(5),
            Arc::new(AtomicBool::new(false)),
        )
        .err()
        .unwrap()
        .to_string();
        assert!(e.contains(want), "{e}");
        assert!(!e.contains('\u{1b}'), "{e}");
        server.join().unwrap();
    }
}

#[test]
fn the_stage_is_reached_over_a_pseudo_terminal_as_a_serial_chain() {
    let head =
        Arc::new(Head::new(Clock::start(), Motion { speed_deg_s: 900.0, overhead_s: 0.02 }, (0.0, 0.0)));
    let stage = Arc::new(ZaberStage::new(head.clone(), ZaberAxes::default(), None));
    let stop = Arc::new(AtomicBool::new(false));
    let (path, threads) = spawn_zaber_pty(stage, &stop).unwrap();
    let mut z = ZaberHead::connect(
        &ZaberPort::Serial(path.clone()),
        ZaberAxes::default(),
        Duration::from_secs(5),
        Arc::new(AtomicBool::new(false)),
    )
    .unwrap();
    assert!(z.describe().starts_with(&format!("zaber:{path} (")), "{}", z.describe());
    z.home().unwrap();
    let got = z.set(&target(45.0, 30.0)).unwrap();
    assert!((got.alpha_deg - 45.0).abs() <= STEP && (got.beta_deg - 30.0).abs() <= STEP, "{got:?}");
    drop(z);
    stop.store(true, Ordering::Relaxed);
    for t in threads {
        t.join().unwrap();
    }
}

#[test]
fn axes_and_ports_are_checked() {
    let mut a = ZaberAxes::default();
    assert!(a.check().is_ok());
    a.deg_per_step = 0.0;
    assert!(a.check().is_err());
    a.deg_per_step = f64::NAN;
    assert!(a.check().is_err());
    a.deg_per_step = 1.0;
    assert!(a.check().is_err());
    let same = ZaberAxes { beta: ZaberAxes::default().alpha, ..ZaberAxes::default() };
    assert!(same.check().unwrap_err().contains("same axis 1/1"));
    assert_eq!("1/2".parse::<Address>(), Ok(Address { device: 1, axis: 2 }));
    for bad in ["0/1", "1/0", "100/1", "1/10", "1", "a/b", "1/1/1", ""] {
        assert!(bad.parse::<Address>().is_err(), "{bad}");
    }
    assert_eq!(ZaberPort::parse("/dev/ttyUSB0"), Some(ZaberPort::Serial("/dev/ttyUSB0".into())));
    assert_eq!(ZaberPort::parse("localhost:55550"), Some(ZaberPort::Tcp("localhost:55550".into())));
    assert_eq!(ZaberPort::parse("COM3"), None);
}
