//! Which head a command drives: the `--head` spec (`manual`, `sim:HOST:PORT`, `zaber:PORT`,
//! `exec:COMMAND`), parsed once into a typed value that settings carry.

use super::zaber::{ZaberAxes, ZaberPort};

/// Which head a command drives.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum HeadSpec {
    /// An operator turns the head by hand; the command shows the angles and waits for Enter.
    Manual,
    /// An emulated head at this TCP address (`HOST:PORT`), as `accelcal emulate` prints it.
    Sim(String),
    /// An adapter: this command line (split as a shell would, [`super::exec::words`]) is started
    /// and speaks the head protocol on its standard input and output.
    Exec(String),
    /// A Zaber head: a serial port (`zaber:/dev/ttyUSB0`) or a TCP address (`zaber:HOST:PORT`),
    /// its axes and scale in [`HeadSettings::zaber`].
    Zaber(ZaberPort),
}

impl std::str::FromStr for HeadSpec {
    type Err = String;
    fn from_str(s: &str) -> Result<HeadSpec, String> {
        if s == "manual" {
            return Ok(HeadSpec::Manual);
        }
        if let Some(command) = s.strip_prefix("exec:") {
            super::exec::words(command)?;
            return Ok(HeadSpec::Exec(command.to_string()));
        }
        if let Some(port) = s.strip_prefix("zaber:") {
            return ZaberPort::parse(port).map(HeadSpec::Zaber).ok_or_else(|| {
                format!(
                    "`{s}`: expected `zaber:/dev/SERIAL_PORT` or `zaber:HOST:PORT` (a Zaber chain's port)"
                )
            });
        }
        match s.strip_prefix("sim:") {
            Some(addr)
                if addr.rsplit_once(':').is_some_and(|(h, p)| !h.is_empty() && p.parse::<u16>().is_ok()) =>
            {
                Ok(HeadSpec::Sim(addr.to_string()))
            }
            _ => Err(format!(
                "`{s}`: expected `manual`, `sim:HOST:PORT` or `zaber:PORT` (the `head` that `accelcal emulate` \
                 prints), or `exec:COMMAND` (an adapter speaking the head protocol)"
            )),
        }
    }
}

impl std::fmt::Display for HeadSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            HeadSpec::Manual => f.write_str("manual"),
            HeadSpec::Sim(a) => write!(f, "sim:{a}"),
            HeadSpec::Exec(c) => write!(f, "exec:{c}"),
            HeadSpec::Zaber(p) => write!(f, "zaber:{p}"),
        }
    }
}

/// The head a command drives and how it is driven, settled from the command line and the
/// station's settings file before any I/O.
#[derive(Clone, Debug, PartialEq)]
pub struct HeadSettings {
    /// Which head.
    pub spec: HeadSpec,
    /// How long a driven head may take to answer a request, a move included
    /// (`--head-timeout-s`); an operator takes the time they need.
    pub timeout: std::time::Duration,
    /// A Zaber head's axes and scale (`--zaber-alpha`, `--zaber-beta`, `--zaber-deg-per-step`;
    /// the defaults for any other head).
    pub zaber: ZaberAxes,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn head_specs() {
        assert_eq!("manual".parse::<HeadSpec>(), Ok(HeadSpec::Manual));
        assert_eq!("sim:127.0.0.1:4000".parse::<HeadSpec>(), Ok(HeadSpec::Sim("127.0.0.1:4000".into())));
        assert!("sim:nowhere".parse::<HeadSpec>().is_err());
        assert!("auto".parse::<HeadSpec>().is_err());
        let spec = "exec:python3 a.py 'h:1'";
        assert_eq!(spec.parse::<HeadSpec>(), Ok(HeadSpec::Exec("python3 a.py 'h:1'".into())));
        assert_eq!(spec.parse::<HeadSpec>().unwrap().to_string(), spec);
        assert!("exec:".parse::<HeadSpec>().is_err() && "exec:a 'b".parse::<HeadSpec>().is_err());
        assert_eq!(
            "zaber:/dev/ttyUSB0".parse::<HeadSpec>(),
            Ok(HeadSpec::Zaber(ZaberPort::Serial("/dev/ttyUSB0".into())))
        );
        assert_eq!(
            "zaber:10.0.0.5:55550".parse::<HeadSpec>(),
            Ok(HeadSpec::Zaber(ZaberPort::Tcp("10.0.0.5:55550".into())))
        );
        assert_eq!("zaber:10.0.0.5:55550".parse::<HeadSpec>().unwrap().to_string(), "zaber:10.0.0.5:55550");
        assert!("zaber:".parse::<HeadSpec>().is_err() && "zaber:ttyUSB0".parse::<HeadSpec>().is_err());
    }
}
