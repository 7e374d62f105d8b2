//! `station --config station.toml`: a line's settings in one reviewed file.
//!
//! Each key is the `station` option of the same name (`_` for `-`; `station` for `--station`),
//! and the nodes are `[[node]]` tables (`port`, `gdb`, `probe`). An option given on the command
//! line overrides its key; `--port` replaces every `[[node]]` (their `gdb` and `probe` too),
//! and `--g`, `--g-u`, `--latitude`, `--height` or `--gravity-asset` replace all five gravity keys. Relative paths (`spec`,
//! a SQLite `db`) are relative to the file's directory, so the file means the same from any
//! working directory.
//!
//! The file is read and checked here, before anything else is opened: an unknown key, a value of
//! the wrong type, a key given twice, a text value that is not one line, and two keys that do not
//! go together are refused with the file's line. The values then go through the same checks as
//! the options they stand for (`settings::check`), whose messages name the key and its line
//! ([`super::Given::name`]).

use std::path::{Path, PathBuf};

use accelcal_core::error::bad;
use serde::Deserialize;
use toml::Spanned;

use super::Given;
use crate::cli::{Command, Range, StationArgs};

/// The file, as written. Every key is optional; a missing one leaves the option's default.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct StationConfig {
    /// The laboratory that issues the certificates.
    laboratory: Option<Spanned<Laboratory>>,
    customer: Option<Spanned<String>>,
    customer_address: Option<Spanned<String>>,
    received: Option<Spanned<String>>,
    min_interval_days: Option<Spanned<f64>>,
    place: Option<Spanned<String>>,
    authorised_by: Option<Spanned<String>>,
    station: Option<Spanned<String>>,
    operator: Option<Spanned<String>>,
    head: Option<Spanned<String>>,
    head_asset: Option<Spanned<String>>,
    thermometer_asset: Option<Spanned<String>>,
    head_timeout_s: Option<Spanned<f64>>,
    head_tolerance_arcsec: Option<Spanned<f64>>,
    settle_s: Option<Spanned<f64>>,
    head_zaber_alpha: Option<Spanned<String>>,
    head_zaber_beta: Option<Spanned<String>>,
    head_zaber_deg_per_step: Option<Spanned<f64>>,
    #[serde(default)]
    node: Vec<Spanned<Node>>,
    plan: Option<Spanned<String>>,
    samples: Option<Spanned<usize>>,
    rate_hz: Option<Spanned<u32>>,
    g: Option<Spanned<f64>>,
    latitude: Option<Spanned<f64>>,
    height: Option<Spanned<f64>>,
    g_u: Option<Spanned<f64>>,
    gravity_asset: Option<Spanned<String>>,
    select_tolerance: Option<Spanned<f64>>,
    verify_samples: Option<Spanned<usize>>,
    criterion: Option<Spanned<String>>,
    coverage: Option<Spanned<f64>>,
    bias_tempco_u: Option<Spanned<f64>>,
    scale_tempco_u: Option<Spanned<f64>>,
    thermometer_u: Option<Spanned<f64>>,
    spec: Option<Spanned<PathBuf>>,
    db: Option<Spanned<String>>,
    anchor_log: Option<Spanned<PathBuf>>,
    baud: Option<Spanned<u32>>,
    timeout_s: Option<Spanned<f64>>,
    chip: Option<Spanned<String>>,
    /// `approve --config`'s: whether a run's operator may approve its certificate. The station
    /// does not read it.
    allow_self_approval: Option<Spanned<bool>>,
}

/// The file's gravity keys.
struct Gravity {
    g: Option<Spanned<f64>>,
    latitude: Option<Spanned<f64>>,
    height: Option<Spanned<f64>>,
    g_u: Option<Spanned<f64>>,
    asset: Option<Spanned<String>>,
}

/// `[laboratory]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Laboratory {
    name: String,
    address: Option<String>,
    country: Option<String>,
}

/// One `[[node]]`: a node on the head.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Node {
    port: String,
    gdb: Option<String>,
    probe: Option<String>,
}

/// `approve --config FILE`: the line's settings file, read and checked whole as the station
/// reads it, for its key `allow_self_approval` (false when absent).
pub fn allow_self_approval(path: &Path) -> anyhow::Result<bool> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| bad(format!("{name}: cannot read: {e}")))?;
    let c: StationConfig =
        toml::from_str(&text).map_err(|e| crate::cmd::spec::toml_error(&name, &text, &e))?;
    Ok(c.allow_self_approval.map(Spanned::into_inner).unwrap_or(false))
}

/// Reads `station --config` and puts each of its keys into the options that were not given on
/// the command line; `given` learns which options the file gave and where, so that the later
/// checks count them as given and name them by their key. Other commands are left alone.
pub fn apply(command: &mut Command, given: &mut Given) -> anyhow::Result<Option<crate::resolved::ConfigUse>> {
    let Command::Station(a) = command else { return Ok(None) };
    let Some(path) = a.config.clone() else {
        if a.ports.is_empty() || a.head.is_none() {
            return Err(bad("station needs --port and --head, or a --config file that gives them"));
        }
        return Ok(None);
    };
    let name = path.display().to_string();
    let text = std::fs::read_to_string(&path).map_err(|e| bad(format!("{name}: cannot read: {e}")))?;
    let c: StationConfig =
        toml::from_str(&text).map_err(|e| crate::cmd::spec::toml_error(&name, &text, &e))?;
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let mut f = File { name: &name, text: &text, given, overridden: Vec::new() };
    f.text_value(&mut a.station_name, "station_name", "station", c.station)?;
    f.text_value(&mut a.operator, "operator", "operator", c.operator)?;
    f.text_value(&mut a.issuer.customer, "customer", "customer", c.customer)?;
    f.text_value(&mut a.issuer.customer_address, "customer_address", "customer_address", c.customer_address)?;
    f.text_value(&mut a.issuer.received, "received", "received", c.received)?;
    f.text_value(&mut a.issuer.place, "place", "place", c.place)?;
    let floor = f.real("min_interval_days", c.min_interval_days, Range::Positive)?;
    f.optional(&mut a.issuer.min_interval_days, "min_interval_days", "min_interval_days", floor);
    f.text_value(&mut a.issuer.authorised_by, "authorised_by", "authorised_by", c.authorised_by)?;
    if let Some(lab) = c.laboratory {
        let at = f.at(&lab);
        let lab = lab.into_inner();
        for (key, v) in
            [("name", Some(&lab.name)), ("address", lab.address.as_ref()), ("country", lab.country.as_ref())]
        {
            if let Some(v) = v {
                accelcal_core::text::single_line(&format!("{name}:{at}: laboratory.{key}"), v)?;
            }
        }
        if f.given.on_command_line("laboratory") {
            f.overridden.push("laboratory.name".into());
        } else {
            a.issuer.laboratory = Some(lab.name);
            f.given.config.push(("laboratory", "laboratory.name".into(), format!("{name}:{at}")));
        }
        if f.given.on_command_line("laboratory_address") {
            f.overridden.push("laboratory.address".into());
        } else if lab.address.is_some() {
            a.issuer.laboratory_address = lab.address;
            f.given.config.push(("laboratory_address", "laboratory.address".into(), format!("{name}:{at}")));
        }
        if f.given.on_command_line("laboratory_country") {
            f.overridden.push("laboratory.country".into());
        } else if lab.country.is_some() {
            a.issuer.laboratory_country = lab.country;
            f.given.config.push(("laboratory_country", "laboratory.country".into(), format!("{name}:{at}")));
        }
    }
    if let Some(head) = &c.head {
        let at = f.at(head);
        head.get_ref()
            .parse::<accelcal_line::head::HeadSpec>()
            .map_err(|e| bad(format!("{name}:{at}: head: {e}")))?;
    }
    f.text_value(&mut a.head, "head", "head", c.head)?;
    f.text_value(&mut a.head_asset, "head_asset", "head_asset", c.head_asset)?;
    f.text_value(&mut a.thermometer_asset, "thermometer_asset", "thermometer_asset", c.thermometer_asset)?;
    f.value(
        &mut a.head_timeout_s,
        "head_timeout_s",
        "head_timeout_s",
        f.real("head_timeout_s", c.head_timeout_s, Range::Seconds)?,
    );
    let tolerance = f.real("head_tolerance_arcsec", c.head_tolerance_arcsec, Range::Arcsec)?;
    f.optional(&mut a.head_tolerance_arcsec, "head_tolerance_arcsec", "head_tolerance_arcsec", tolerance);
    let settle = f.real("settle_s", c.settle_s, Range::SecondsOrZero)?;
    f.optional(&mut a.settle_s, "settle_s", "settle_s", settle);
    let alpha = f.zaber_axis("zaber_alpha", "head_zaber_alpha", c.head_zaber_alpha)?;
    f.optional(&mut a.zaber.zaber_alpha, "zaber_alpha", "head_zaber_alpha", alpha);
    let beta = f.zaber_axis("zaber_beta", "head_zaber_beta", c.head_zaber_beta)?;
    f.optional(&mut a.zaber.zaber_beta, "zaber_beta", "head_zaber_beta", beta);
    let scale = f.real("head_zaber_deg_per_step", c.head_zaber_deg_per_step, Range::DegPerStep)?;
    f.optional(&mut a.zaber.zaber_deg_per_step, "zaber_deg_per_step", "head_zaber_deg_per_step", scale);
    f.nodes(a, c.node)?;
    f.text_value_plain(&mut a.plan, "plan", c.plan)?;
    let samples = f.checked("samples", c.samples, |n| Range::Sets.count(n).map_err(|m| format!(" {m}")))?;
    f.value(&mut a.samples, "samples", "samples", samples);
    let rate_hz = f.checked("rate_hz", c.rate_hz, crate::cli::range::rate_hz)?;
    f.optional(&mut a.rate_hz, "rate_hz", "rate_hz", rate_hz);
    f.gravity(
        a,
        Gravity { g: c.g, latitude: c.latitude, height: c.height, g_u: c.g_u, asset: c.gravity_asset },
    )?;
    let select_tolerance = f.real("select_tolerance", c.select_tolerance, Range::Codes)?;
    f.value(&mut a.select_tolerance, "select_tolerance", "select_tolerance", select_tolerance);
    let verify_samples =
        f.checked("verify_samples", c.verify_samples, |n| Range::Sets.count(n).map_err(|m| format!(" {m}")))?;
    f.optional(&mut a.verify_samples, "verify_samples", "verify_samples", verify_samples);
    if let Some(v) = c.criterion.filter(|_| !f.given.on_command_line("criterion")) {
        use clap::ValueEnum as _;
        let parsed = crate::cli::CriterionArg::from_str(v.get_ref(), false).map_err(|_| {
            bad(format!(
                "`criterion` ({}:{}): `{}`: expected regularity, symmetric, rss or loo",
                f.name,
                f.at(&v),
                v.get_ref()
            ))
        })?;
        f.value(&mut a.criterion, "criterion", "criterion", Some(Spanned::new(v.span(), parsed)));
    }
    let coverage = f.real("coverage", c.coverage, Range::Coverage)?;
    f.optional(&mut a.coverage, "coverage", "coverage", coverage);
    let tempco = [
        ("bias_tempco_u", &c.bias_tempco_u),
        ("scale_tempco_u", &c.scale_tempco_u),
        ("thermometer_u", &c.thermometer_u),
    ];
    for (key, v) in tempco {
        if let Some(v) = v {
            if let Err(m) = Range::Sigma.check(*v.get_ref()) {
                return Err(bad(format!("{name}:{}: {key} {m}", f.at(v))));
            }
        }
    }
    f.optional(&mut a.tempco.bias_tempco_u, "bias_tempco_u", "bias_tempco_u", c.bias_tempco_u);
    f.optional(&mut a.tempco.scale_tempco_u, "scale_tempco_u", "scale_tempco_u", c.scale_tempco_u);
    f.optional(&mut a.tempco.thermometer_u, "thermometer_u", "thermometer_u", c.thermometer_u);
    let t = &a.tempco;
    let set = [t.bias_tempco_u, t.scale_tempco_u, t.thermometer_u].iter().filter(|v| v.is_some()).count();
    if set != 0 && set != 3 {
        return Err(bad(format!(
            "{name}: bias_tempco_u, scale_tempco_u and thermometer_u go together (the budget's temperature needs all three)"
        )));
    }
    if let Some(s) = &c.spec {
        // The path reaches the steps' command lines and the journal: one line, as a key's text.
        accelcal_core::text::single_line(
            &format!("{name}:{}: spec", f.at(s)),
            &s.get_ref().to_string_lossy(),
        )?;
    }
    let spec = c.spec.map(|s| {
        let span = s.span();
        let p = s.into_inner();
        Spanned::new(span, if p.is_relative() { dir.join(p) } else { p })
    });
    f.optional(&mut a.spec, "spec", "spec", spec);
    let db = c.db.map(|s| {
        let span = s.span();
        let v = s.into_inner();
        let path = Path::new(&v);
        let v =
            if v.contains("://") || !path.is_relative() { v } else { dir.join(path).display().to_string() };
        Spanned::new(span, v)
    });
    f.text_value(&mut a.db, "db", "db", db)?;
    let anchor_log = c.anchor_log.map(|s| {
        let span = s.span();
        let p = s.into_inner();
        Spanned::new(span, if p.is_relative() { dir.join(p) } else { p })
    });
    f.optional(&mut a.anchor_log, "anchor_log", "anchor_log", anchor_log);
    f.value(&mut a.baud, "baud", "baud", c.baud);
    let timeout_s = f.real("timeout_s", c.timeout_s, Range::Seconds)?;
    f.value(&mut a.timeout_s, "timeout_s", "timeout_s", timeout_s);
    f.text_value_plain(&mut a.chip, "chip", c.chip)?;
    let mut keys: Vec<String> = f.given.config.iter().map(|(_, key, _)| key.clone()).collect();
    keys.dedup();
    let overridden = f.overridden;
    if a.ports.is_empty() || a.head.is_none() {
        let missing = if a.ports.is_empty() { "no [[node]] and no --port" } else { "no head and no --head" };
        return Err(bad(format!("{name}: {missing}: the station needs its nodes and its head")));
    }
    Ok(Some(crate::resolved::ConfigUse { path, keys, overridden }))
}

/// The file being applied.
struct File<'f, 'g, 'm> {
    name: &'f str,
    text: &'f str,
    given: &'g mut Given<'m>,
    /// The file's keys the command line overrode.
    overridden: Vec<String>,
}

impl File<'_, '_, '_> {
    /// `LINE:COL` of a key's value.
    fn at<T>(&self, v: &Spanned<T>) -> String {
        crate::cmd::spec::line_col(self.text, v.span().start)
    }

    /// Whether the option `id` takes the file's value (it was not given on the command line),
    /// noting it as given by the file.
    fn takes<T>(&mut self, id: &'static str, key: &str, v: &Spanned<T>) -> bool {
        if self.given.on_command_line(id) {
            self.overridden.push(key.to_string());
            return false;
        }
        let at = format!("{}:{}", self.name, self.at(v));
        self.given.config.push((id, key.to_string(), at));
        true
    }

    /// `v`, when it is in the range its option's value parser accepts on the command line
    /// (`check` says what it must be after the key's name); otherwise the refusal, which names the
    /// key and its line as the later checks do (`` `samples` (station.toml:5:11) must be ...``).
    /// `key` is also the option's clap id.
    fn checked<T: Copy>(
        &self,
        key: &str,
        v: Option<Spanned<T>>,
        check: impl Fn(T) -> Result<T, String>,
    ) -> anyhow::Result<Option<Spanned<T>>> {
        // A value the command line overrides is not used, and not checked (the command line's
        // was, by its value parser).
        if let Some(v) = v.as_ref().filter(|_| !self.given.on_command_line(key)) {
            if let Err(m) = check(*v.get_ref()) {
                return Err(bad(format!("`{key}` ({}:{}){m}", self.name, self.at(v))));
            }
        }
        Ok(v)
    }

    /// A Zaber axis, `D/A` (`head_zaber_alpha`, `head_zaber_beta`), parsed as `--zaber-alpha`
    /// parses it; refused naming the key and its line. Not checked when the command line gives
    /// option `id`.
    fn zaber_axis(
        &self,
        id: &str,
        key: &str,
        v: Option<Spanned<String>>,
    ) -> anyhow::Result<Option<Spanned<accelcal_line::head::zaber::codec::Address>>> {
        let Some(v) = v else { return Ok(None) };
        if self.given.on_command_line(id) {
            // Overridden: not used, not checked (`optional` notes it).
            return Ok(Some(Spanned::new(v.span(), accelcal_line::head::ZaberAxes::default().alpha)));
        }
        match crate::cli::parse_zaber_axis(v.get_ref()) {
            Ok(a) => Ok(Some(Spanned::new(v.span(), a))),
            Err(m) => Err(bad(format!("`{key}` ({}:{}): {m}", self.name, self.at(&v)))),
        }
    }

    /// [`File::checked`] for a number in a [`Range`].
    fn real(&self, key: &str, v: Option<Spanned<f64>>, range: Range) -> anyhow::Result<Option<Spanned<f64>>> {
        self.checked(key, v, |x| range.check(x).map_err(|m| format!(" {m}")))
    }

    /// An option with a default.
    fn value<T>(&mut self, target: &mut T, id: &'static str, key: &str, v: Option<Spanned<T>>) {
        if let Some(v) = v {
            if self.takes(id, key, &v) {
                *target = v.into_inner();
            }
        }
    }

    /// An option without a default.
    fn optional<T>(&mut self, target: &mut Option<T>, id: &'static str, key: &str, v: Option<Spanned<T>>) {
        if let Some(v) = v {
            if self.takes(id, key, &v) {
                *target = Some(v.into_inner());
            }
        }
    }

    /// An option of text, which must be one line (it reaches the journal, the database or the
    /// certificate).
    fn text_value(
        &mut self,
        target: &mut Option<String>,
        id: &'static str,
        key: &str,
        v: Option<Spanned<String>>,
    ) -> anyhow::Result<()> {
        if let Some(v) = &v {
            let field = format!("{}:{}: {key}", self.name, self.at(v));
            accelcal_core::text::single_line(&field, v.get_ref())?;
        }
        self.optional(target, id, key, v);
        Ok(())
    }

    /// An option of text with a default.
    fn text_value_plain(
        &mut self,
        target: &mut String,
        id: &'static str,
        v: Option<Spanned<String>>,
    ) -> anyhow::Result<()> {
        let mut o = None;
        self.text_value(&mut o, id, id, v)?;
        if let Some(v) = o {
            *target = v;
        }
        Ok(())
    }

    /// `[[node]]`: the ports, and the GDB servers or probes of all nodes or of none; not taken
    /// when `--port` is given.
    fn nodes(&mut self, a: &mut StationArgs, nodes: Vec<Spanned<Node>>) -> anyhow::Result<()> {
        let Some(first) = nodes.first() else { return Ok(()) };
        let at_first = self.at(first);
        for n in &nodes {
            let at = format!("{}:{}", self.name, self.at(n));
            let n = n.get_ref();
            for (key, v) in [("port", Some(&n.port)), ("gdb", n.gdb.as_ref()), ("probe", n.probe.as_ref())] {
                if let Some(v) = v {
                    accelcal_core::text::single_line(&format!("{at}: node.{key}"), v)?;
                }
            }
        }
        let all_or_none = |key: &str, count: usize| {
            if count == 0 || count == nodes.len() {
                return Ok(());
            }
            Err(bad(format!(
                "{}:{at_first}: {count} of {} [[node]] give {key}: give it for every node or for none",
                self.name,
                nodes.len()
            )))
        };
        all_or_none("gdb", nodes.iter().filter(|n| n.get_ref().gdb.is_some()).count())?;
        all_or_none("probe", nodes.iter().filter(|n| n.get_ref().probe.is_some()).count())?;
        if self.given.on_command_line("ports") {
            self.overridden.push("[[node]]".into());
            return Ok(());
        }
        let at = format!("{}:{at_first}", self.name);
        let nodes: Vec<Node> = nodes.into_iter().map(Spanned::into_inner).collect();
        self.given.config.push(("ports", "node.port".into(), at.clone()));
        a.ports = nodes.iter().map(|n| n.port.clone()).collect();
        let gdb: Vec<String> = nodes.iter().filter_map(|n| n.gdb.clone()).collect();
        let probe: Vec<String> = nodes.iter().filter_map(|n| n.probe.clone()).collect();
        for (id, key, values, target) in
            [("gdb", "node.gdb", gdb, &mut a.gdb), ("probe", "node.probe", probe, &mut a.probe)]
        {
            if values.is_empty() {
                continue;
            }
            if self.given.on_command_line(id) {
                self.overridden.push(key.into());
            } else {
                self.given.config.push((id, key.into(), at.clone()));
                *target = values;
            }
        }
        Ok(())
    }

    /// `g` (and `g_u`), `latitude` (and `height`) or `gravity_asset`: none taken when the command
    /// line gives gravity.
    fn gravity(&mut self, a: &mut StationArgs, c: Gravity) -> anyhow::Result<()> {
        let name = self.name;
        let clash = |this: &dyn Fn() -> String, k: &str, other: String| {
            bad(format!("{name}:{}: {k} and {} both give gravity: keep one of them", this(), other))
        };
        if let (Some(g), Some(l)) = (&c.g, &c.latitude) {
            return Err(clash(&|| self.at(g), "g", format!("latitude (at {})", self.at(l))));
        }
        if let Some(asset) = &c.asset {
            let other = [
                ("g", c.g.as_ref().map(|v| self.at(v))),
                ("latitude", c.latitude.as_ref().map(|v| self.at(v))),
            ]
            .into_iter()
            .chain([("g_u", c.g_u.as_ref().map(|v| self.at(v)))])
            .find_map(|(k, at)| at.map(|at| format!("{k} (at {at})")));
            if let Some(other) = other {
                return Err(clash(&|| self.at(asset), "gravity_asset", other));
            }
        }
        if let (Some(h), None) = (&c.height, &c.latitude) {
            return Err(bad(format!(
                "{name}:{}: height needs latitude (it corrects the normal gravity there)",
                self.at(h)
            )));
        }
        if let (Some(u), None) = (&c.g_u, &c.g) {
            return Err(bad(format!(
                "{name}:{}: g_u needs g: it is the standard uncertainty of that g",
                self.at(u)
            )));
        }
        if ["g", "latitude", "height", "g_u", "gravity_asset"].iter().any(|id| self.given.on_command_line(id))
        {
            let keys = [
                ("g", c.g.is_some()),
                ("latitude", c.latitude.is_some()),
                ("height", c.height.is_some()),
                ("g_u", c.g_u.is_some()),
                ("gravity_asset", c.asset.is_some()),
            ];
            self.overridden.extend(keys.iter().filter(|(_, v)| *v).map(|(k, _)| k.to_string()));
            return Ok(());
        }
        self.optional(&mut a.g, "g", "g", c.g);
        self.optional(&mut a.local.latitude, "latitude", "latitude", c.latitude);
        self.optional(&mut a.local.height, "height", "height", c.height);
        self.optional(&mut a.local.g_u, "g_u", "g_u", c.g_u);
        self.text_value(&mut a.gravity_asset, "gravity_asset", "gravity_asset", c.asset)?;
        Ok(())
    }
}
