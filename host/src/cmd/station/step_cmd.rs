//! The station's steps as values. Each step's command is a [`StepCommand`] built from the
//! station's settings; [`StepCommand::args`] is the one place that spells it as the command line
//! the child process runs, and [`StepCommand::journalled`] the line the journal keeps for people
//! (the database named without its password). A test parses every variant's line with the CLI
//! and compares what the command would run with the values.

use std::path::PathBuf;

use accelcal_core::uncertainty::TempCoefficients;
use accelcal_db::RunId;

pub(super) use crate::settings::values::{FlashRoute, Issuer};

/// A node link as `info`, `acquire` and `verify` take it.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Link {
    /// One port per node (`acquire` takes several).
    pub ports: Vec<String>,
    pub baud: u32,
    /// How long a request waits for its answer, s.
    pub timeout_s: f64,
}

/// The dividing head and how it is driven: how long a move may take (s), the read-back
/// tolerance (arcsec) and the wait after a move (s). A manual head has no timeout and no
/// tolerance (the operator's word is the read-back); the tolerance and the wait are passed on only
/// when the station was given them.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Head {
    pub spec: accelcal_line::head::HeadSpec,
    pub timeout_s: Option<f64>,
    pub tolerance_arcsec: Option<f64>,
    pub settle_s: Option<f64>,
    /// A Zaber head's axes and scale, each passed on when given.
    pub zaber: crate::cli::ZaberArgs,
}

/// The head's stated uncertainties, arcsec.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct HeadU {
    pub angle_arcsec: f64,
    pub orthogonality_arcsec: f64,
}

/// Gravity as the user stated it (m/s²; or latitude in degrees and height in m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum GravityGiven {
    /// `--g`, and `--g-u` when it has a stated uncertainty.
    G {
        g: f64,
        u: Option<f64>,
    },
    Site {
        latitude: f64,
        height: f64,
    },
}

/// The run a step stores its piece in: the database as given, and the run.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct DbRun {
    pub spec: String,
    pub run: RunId,
    /// `--anchor-log`, passed on to the step.
    pub anchor_log: Option<std::path::PathBuf>,
}

/// What a verification judges the errors against.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Against {
    /// The measured scatter, with the coverage factor when one is given.
    Scatter { coverage: Option<f64> },
    /// A product specification, with the head's uncertainties its budget takes.
    Spec { file: PathBuf, head_u: Option<HeadU> },
}

/// A step's command.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum StepCommand {
    Info {
        link: Link,
        json: PathBuf,
    },
    Acquire {
        link: Link,
        head: Head,
        plan: String,
        samples: usize,
        /// Each node's unit: serial and campaign file, in the ports' order.
        units: Vec<(String, PathBuf)>,
        rate_hz: Option<u32>,
        gravity: Option<GravityGiven>,
        resume: bool,
    },
    Select {
        campaign: PathBuf,
        json: PathBuf,
        /// ADC codes.
        tolerance: f64,
        /// The external criterion (written only when not the default, regularity).
        criterion: crate::cli::CriterionArg,
    },
    Fit {
        campaign: PathBuf,
        record: PathBuf,
        json: PathBuf,
        device_id: String,
        head_u: Option<HeadU>,
        /// The unit type's temperature coefficients, which the budget takes.
        tempco: Option<TempCoefficients>,
    },
    Flash {
        record: PathBuf,
        db: DbRun,
        route: FlashRoute,
        /// The node's link, for the confirmation after the reset.
        port: String,
        baud: u32,
    },
    Verify {
        link: Link,
        head: Head,
        plan: String,
        samples: usize,
        json: PathBuf,
        fit: Option<PathBuf>,
        against: Against,
        gravity: Option<GravityGiven>,
    },
    Report {
        campaign: PathBuf,
        record: PathBuf,
        fit: PathBuf,
        verify: PathBuf,
        out: PathBuf,
        pdf: PathBuf,
        as_found: Option<PathBuf>,
        issuer: Issuer,
        db: DbRun,
    },
}

/// A command line being spelled.
struct Line {
    args: Vec<String>,
    /// How the database is named: as given, or (the journal) without its password.
    db_shown: Option<String>,
}

impl Line {
    fn word(&mut self, w: &str) {
        self.args.push(w.to_string());
    }

    fn opt(&mut self, flag: &str, v: impl ToString) {
        self.args.extend([flag.to_string(), v.to_string()]);
    }

    fn path(&mut self, flag: &str, p: &std::path::Path) {
        self.opt(flag, p.display());
    }

    fn maybe(&mut self, flag: &str, v: Option<impl ToString>) {
        if let Some(v) = v {
            self.opt(flag, v);
        }
    }

    fn link(&mut self, l: &Link) {
        for p in &l.ports {
            self.opt("--port", p);
        }
        self.opt("--baud", l.baud);
        self.opt("--timeout-s", l.timeout_s);
    }

    fn head(&mut self, h: &Head, plan: &str) {
        self.opt("--head", &h.spec);
        self.opt("--plan", plan);
        self.maybe("--head-timeout-s", h.timeout_s);
        self.maybe("--head-tolerance-arcsec", h.tolerance_arcsec);
        self.maybe("--settle-s", h.settle_s);
        self.maybe("--zaber-alpha", h.zaber.zaber_alpha);
        self.maybe("--zaber-beta", h.zaber.zaber_beta);
        self.maybe("--zaber-deg-per-step", h.zaber.zaber_deg_per_step);
    }

    fn head_u(&mut self, u: Option<HeadU>) {
        if let Some(u) = u {
            self.opt("--head-angle-u", u.angle_arcsec);
            self.opt("--head-orthogonality-u", u.orthogonality_arcsec);
        }
    }

    fn gravity(&mut self, g: Option<GravityGiven>) {
        match g {
            Some(GravityGiven::G { g, u }) => {
                self.opt("--g", g);
                if let Some(u) = u {
                    self.opt("--g-u", u);
                }
            }
            Some(GravityGiven::Site { latitude, height }) => {
                self.opt("--latitude", latitude);
                if height != 0.0 {
                    self.opt("--height", height);
                }
            }
            None => {}
        }
    }

    fn db(&mut self, d: &DbRun) {
        let shown = self.db_shown.clone().unwrap_or_else(|| d.spec.clone());
        self.opt("--db", shown);
        self.opt("--run-id", d.run);
        if let Some(l) = &d.anchor_log {
            self.path("--anchor-log", l);
        }
    }
}

impl StepCommand {
    /// The command line (without the program's name) the child runs.
    pub fn args(&self) -> Vec<String> {
        self.spell(None)
    }

    /// The command line as the journal keeps it and the station prints it: the database named
    /// as `target` (its spec without a password).
    pub fn journalled(&self, target: &str) -> Vec<String> {
        self.spell(Some(target.to_string()))
    }

    fn spell(&self, db_shown: Option<String>) -> Vec<String> {
        let mut l = Line { args: Vec::new(), db_shown };
        match self {
            StepCommand::Info { link, json } => {
                l.word("info");
                l.link(link);
                l.path("--json", json);
            }
            StepCommand::Acquire { link, head, plan, samples, units, rate_hz, gravity, resume } => {
                l.word("acquire");
                l.link(link);
                l.head(head, plan);
                l.opt("--samples", samples);
                for (serial, out) in units {
                    l.opt("--serial", serial);
                    l.path("--out", out);
                }
                l.maybe("--rate-hz", *rate_hz);
                l.gravity(*gravity);
                if *resume {
                    l.word("--resume");
                }
            }
            StepCommand::Select { campaign, json, tolerance, criterion } => {
                l.word("select");
                l.word(&campaign.display().to_string());
                l.path("--json", json);
                l.opt("--tolerance", tolerance);
                if *criterion != crate::cli::CriterionArg::Regularity {
                    use clap::ValueEnum as _;
                    let name = criterion.to_possible_value().expect("a named criterion");
                    l.opt("--criterion", name.get_name().to_string());
                }
            }
            StepCommand::Fit { campaign, record, json, device_id, head_u, tempco } => {
                l.word("fit");
                l.word(&campaign.display().to_string());
                l.path("--record", record);
                l.path("--json", json);
                l.opt("--device-id", device_id);
                l.head_u(*head_u);
                if let Some(t) = tempco {
                    l.opt("--bias-tempco-u", t.bias_mg_per_c);
                    l.opt("--scale-tempco-u", t.scale_ppm_per_c);
                    l.opt("--thermometer-u", t.thermometer_c);
                }
            }
            StepCommand::Flash { record, db, route, port, baud } => {
                l.word("flash");
                l.word(&record.display().to_string());
                l.db(db);
                match route {
                    FlashRoute::Gdb(g) => l.opt("--gdb", g),
                    FlashRoute::Probe { chip, probe } => {
                        l.opt("--chip", chip);
                        l.maybe("--probe", probe.as_ref());
                    }
                }
                l.opt("--port", port);
                l.opt("--baud", baud);
            }
            StepCommand::Verify { link, head, plan, samples, json, fit, against, gravity } => {
                l.word("verify");
                l.link(link);
                l.head(head, plan);
                l.opt("--samples", samples);
                l.path("--json", json);
                l.maybe("--fit", fit.as_ref().map(|p| p.display()));
                match against {
                    Against::Scatter { coverage } => l.maybe("--coverage", *coverage),
                    Against::Spec { file, head_u } => {
                        l.path("--spec", file);
                        l.head_u(*head_u);
                    }
                }
                l.gravity(*gravity);
            }
            StepCommand::Report { campaign, record, fit, verify, out, pdf, as_found, issuer, db } => {
                l.word("report");
                l.path("--campaign", campaign);
                l.path("--record", record);
                l.path("--fit", fit);
                l.path("--verify", verify);
                l.path("--out", out);
                l.path("--pdf", pdf);
                l.maybe("--as-found", as_found.as_ref().map(|p| p.display()));
                l.maybe("--laboratory", issuer.laboratory.as_ref());
                l.maybe("--laboratory-address", issuer.laboratory_address.as_ref());
                l.maybe("--laboratory-country", issuer.laboratory_country.as_ref());
                l.maybe("--ambient-c", issuer.ambient_c.as_ref());
                l.maybe("--customer", issuer.customer.as_ref());
                l.maybe("--customer-address", issuer.customer_address.as_ref());
                l.maybe("--received", issuer.received.as_ref());
                l.maybe("--place", issuer.place.as_ref());
                l.maybe("--authorised-by", issuer.authorised_by.as_ref());
                l.maybe("--interval-days", issuer.interval_days.as_ref());
                l.maybe("--min-interval-days", issuer.min_interval_days.as_ref());
                l.db(db);
            }
        }
        l.args
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cli::{Cli, Command};
    use clap::Parser;

    fn parse(c: &StepCommand) -> Command {
        let line = std::iter::once("accelcal".to_string()).chain(c.args());
        Cli::try_parse_from(line).unwrap_or_else(|e| panic!("{:?}: {e}", c.args())).command
    }

    fn link(ports: &[&str]) -> Link {
        Link { ports: ports.iter().map(|p| p.to_string()).collect(), baud: 921_600, timeout_s: 2.5 }
    }

    fn sim() -> Head {
        Head {
            spec: "sim:127.0.0.1:4000".parse().unwrap(),
            timeout_s: Some(90.0),
            tolerance_arcsec: Some(20.0),
            settle_s: None,
            zaber: Default::default(),
        }
    }

    fn db() -> DbRun {
        DbRun {
            spec: "host=/tmp/pg user=a password=secret dbname=d".into(),
            run: RunId::parse("0123456789abcdef0123456789abcdef").expect("a run id"),
            anchor_log: Some("/var/lib/accelcal/anchors.log".into()),
        }
    }

    const HEAD_U: HeadU = HeadU { angle_arcsec: 12.5, orthogonality_arcsec: 3.0 };

    /// Every step's line parses as the command it names, with the values it was built from.
    #[test]
    fn each_step_s_line_is_its_command_with_its_values() {
        let c = StepCommand::Info { link: link(&["/dev/pts/3"]), json: "u/info.json".into() };
        let Command::Info(a) = parse(&c) else { panic!("info") };
        assert_eq!((a.link.port.as_str(), a.link.baud, a.link.timeout_s), ("/dev/pts/3", 921_600, 2.5));
        assert_eq!(a.json, Some("u/info.json".into()));

        let c = StepCommand::Acquire {
            link: link(&["/dev/pts/3", "/dev/pts/4"]),
            head: sim(),
            plan: "random:24".into(),
            samples: 200,
            units: vec![("A-1".into(), "a/c.csv".into()), ("A-2".into(), "b/c.csv".into())],
            rate_hz: Some(1000),
            gravity: Some(GravityGiven::Site { latitude: -33.9, height: 120.0 }),
            resume: true,
        };
        let Command::Acquire(a) = parse(&c) else { panic!("acquire") };
        assert_eq!(a.port, ["/dev/pts/3", "/dev/pts/4"]);
        assert_eq!((a.baud, a.timeout_s, a.head_timeout_s), (921_600, 2.5, 90.0));
        assert_eq!((a.head_tolerance_arcsec, a.settle_s), (20.0, 0.0));
        assert_eq!((a.head.to_string().as_str(), a.plan.as_str()), ("sim:127.0.0.1:4000", "random:24"));
        assert_eq!((a.samples, a.rate_hz, a.resume), (Some(200), Some(1000), true));
        assert_eq!(a.serial, ["A-1", "A-2"]);
        assert_eq!(a.out, [PathBuf::from("a/c.csv"), PathBuf::from("b/c.csv")]);
        assert_eq!((a.g, a.local.latitude, a.local.height), (None, Some(-33.9), Some(120.0)));
        assert_eq!(a.zaber, crate::cli::ZaberArgs::default(), "none given, none passed");

        // A Zaber head's axes and scale reach the step as given.
        let zaber = crate::cli::ZaberArgs {
            zaber_alpha: Some("3/1".parse().unwrap()),
            zaber_beta: Some("3/2".parse().unwrap()),
            zaber_deg_per_step: Some(0.001),
        };
        let head = Head { spec: "zaber:/dev/ttyUSB0".parse().unwrap(), zaber: zaber.clone(), ..sim() };
        let c = StepCommand::Acquire {
            link: link(&["/dev/pts/3"]),
            head,
            plan: "six".into(),
            samples: 200,
            units: vec![("A-1".into(), "a/c.csv".into())],
            rate_hz: None,
            gravity: None,
            resume: false,
        };
        let Command::Acquire(a) = parse(&c) else { panic!("acquire") };
        assert_eq!((a.head.to_string().as_str(), a.zaber), ("zaber:/dev/ttyUSB0", zaber));

        let c = StepCommand::Select {
            campaign: "c.csv".into(),
            json: "s.json".into(),
            tolerance: 5.0,
            criterion: crate::cli::CriterionArg::Regularity,
        };
        let Command::Select(a) = parse(&c) else { panic!("select") };
        assert_eq!((a.campaign, a.common.json, a.tolerance), ("c.csv".into(), Some("s.json".into()), 5.0));
        assert!(!c.args().iter().any(|w| w == "--criterion"), "the default is not spelled");
        let c = StepCommand::Select {
            campaign: "c.csv".into(),
            json: "s.json".into(),
            tolerance: 1.0,
            criterion: crate::cli::CriterionArg::Loo,
        };
        let Command::Select(a) = parse(&c) else { panic!("select") };
        assert_eq!(a.criterion, crate::cli::CriterionArg::Loo);

        let c = StepCommand::Fit {
            campaign: "c.csv".into(),
            record: "r.rec".into(),
            json: "f.json".into(),
            device_id: "0123456789abcdef01234567".into(),
            head_u: Some(HEAD_U),
            tempco: Some(TempCoefficients { bias_mg_per_c: 0.1, scale_ppm_per_c: 40.0, thermometer_c: 0.5 }),
        };
        let Command::Fit(a) = parse(&c) else { panic!("fit") };
        assert_eq!(
            (a.campaign, a.record, a.common.json),
            ("c.csv".into(), Some("r.rec".into()), Some("f.json".into()))
        );
        assert_eq!(a.device_id.as_deref(), Some("0123456789abcdef01234567"));
        assert_eq!((a.head_angle_u, a.head_orthogonality_u), (Some(12.5), Some(3.0)));
        let t = a.tempco;
        assert_eq!((t.bias_tempco_u, t.scale_tempco_u, t.thermometer_u), (Some(0.1), Some(40.0), Some(0.5)));

        let d = db();
        for route in [
            FlashRoute::Gdb("127.0.0.1:3333".into()),
            FlashRoute::Probe { chip: "STM32L475VGTx".into(), probe: Some("0483:374b".into()) },
        ] {
            let c = StepCommand::Flash {
                record: "r.rec".into(),
                db: d.clone(),
                route: route.clone(),
                port: "/dev/ttyACM0".into(),
                baud: 921_600,
            };
            let Command::Flash(a) = parse(&c) else { panic!("flash") };
            assert_eq!(a.record, PathBuf::from("r.rec"));
            assert_eq!((a.run.db.as_deref(), a.run.run_id), (Some(d.spec.as_str()), Some(d.run.to_string())));
            assert_eq!(a.run.anchor_log, d.anchor_log, "the anchor log is passed on");
            assert_eq!((a.port.as_deref(), a.baud), (Some("/dev/ttyACM0"), 921_600));
            match route {
                FlashRoute::Gdb(g) => assert_eq!(a.gdb, Some(g)),
                FlashRoute::Probe { chip, probe } => {
                    assert_eq!((a.gdb, a.chip, a.probe), (None, chip, probe))
                }
            }
        }

        let verify = |against| StepCommand::Verify {
            link: link(&["/dev/pts/3"]),
            head: Head {
                spec: accelcal_line::head::HeadSpec::Manual,
                timeout_s: None,
                tolerance_arcsec: None,
                settle_s: Some(1.5),
                zaber: Default::default(),
            },
            plan: "six".into(),
            samples: 300,
            json: "v.json".into(),
            fit: Some("f.json".into()),
            against,
            gravity: Some(GravityGiven::G { g: 9.80123, u: None }),
        };
        let c = verify(Against::Scatter { coverage: Some(3.0) });
        let Command::Verify(a) = parse(&c) else { panic!("verify") };
        assert_eq!((a.head.to_string().as_str(), a.plan.as_str(), a.samples), ("manual", "six", 300));
        assert_eq!(a.settle_s, 1.5);
        assert_eq!(
            (a.json, a.fit, a.coverage, a.spec),
            (Some("v.json".into()), Some("f.json".into()), Some(3.0), None)
        );
        assert_eq!((a.g, a.local.latitude), (Some(9.80123), None));
        let c = verify(Against::Spec { file: "spec.toml".into(), head_u: Some(HEAD_U) });
        let Command::Verify(a) = parse(&c) else { panic!("verify") };
        assert_eq!((a.spec, a.coverage), (Some("spec.toml".into()), None));
        assert_eq!((a.head_angle_u, a.head_orthogonality_u), (Some(12.5), Some(3.0)));

        let c = StepCommand::Report {
            campaign: "c.csv".into(),
            record: "r.rec".into(),
            fit: "f.json".into(),
            verify: "v.json".into(),
            out: "cert.html".into(),
            pdf: "cert.pdf".into(),
            as_found: Some("af.json".into()),
            issuer: Issuer {
                laboratory: Some("Lab".into()),
                customer: Some("C".into()),
                place: Some("line 2, Kyiv".into()),
                ..Issuer::default()
            },
            db: d.clone(),
        };
        let Command::Report(a) = parse(&c) else { panic!("report") };
        assert_eq!((a.campaign, a.record, a.fit), ("c.csv".into(), "r.rec".into(), "f.json".into()));
        assert_eq!(
            (a.verify, a.out, a.as_found),
            (Some("v.json".into()), "cert.html".into(), Some("af.json".into()))
        );
        assert_eq!(a.pdf, Some("cert.pdf".into()));
        let i = a.issuer;
        assert_eq!(i.place.as_deref(), Some("line 2, Kyiv"));
        assert_eq!(
            (i.laboratory, i.laboratory_address, i.customer, i.authorised_by),
            (Some("Lab".into()), None, Some("C".into()), None)
        );
        assert_eq!(a.run.db.as_deref(), Some(d.spec.as_str()));
    }

    /// The journal's line names the database by its target: no password, the rest as run.
    #[test]
    fn the_journal_s_line_names_the_database_without_its_password() {
        let c = StepCommand::Flash {
            record: "r.rec".into(),
            db: db(),
            route: FlashRoute::Gdb("127.0.0.1:3333".into()),
            port: "/dev/pts/3".into(),
            baud: 921_600,
        };
        let (run, kept) = (c.args(), c.journalled("host=/tmp/pg user=a dbname=d"));
        assert!(run.iter().any(|a| a.contains("secret")));
        assert!(!kept.iter().any(|a| a.contains("secret")), "{kept:?}");
        assert_eq!(run.len(), kept.len());
        let differ: Vec<usize> = (0..run.len()).filter(|&i| run[i] != kept[i]).collect();
        assert_eq!(differ.len(), 1, "{kept:?}");
    }
}
