//! A fault the emulated head injects once (`accelcal emulate --head-fault KIND --head-fault-at
//! N`): at the N-th move it receives since it started (1-based), so that the same command run
//! again meets no fault.

/// What goes wrong.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FaultKind {
    /// The move is refused (Zaber: `RJ`; the line protocol: `ERR`).
    Reject,
    /// The α axis stalls half-way (Zaber: fault flag `FS`).
    Stall,
    /// A limit sensor stops the α axis half-way (Zaber: warning flag `WL`).
    Limit,
    /// The α axis has lost its reference position (Zaber: `WH`), so it refuses the move.
    NotHomed,
    /// No reply to the move, and no motion.
    Silent,
    /// The head lands this far from the commanded α, arcsec, and its read-back says so.
    Off(f64),
}

/// A fault and the move it strikes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadFault {
    /// What goes wrong.
    pub kind: FaultKind,
    /// The move it strikes, 1-based, counted from the emulator's start.
    pub at_move: u64,
}

impl std::str::FromStr for FaultKind {
    type Err = String;
    fn from_str(s: &str) -> Result<FaultKind, String> {
        Ok(match s {
            "reject" => FaultKind::Reject,
            "stall" => FaultKind::Stall,
            "limit" => FaultKind::Limit,
            "not-homed" => FaultKind::NotHomed,
            "silent" => FaultKind::Silent,
            _ => match s.strip_prefix("off=").map(str::parse::<f64>) {
                Some(Ok(a)) if a.is_finite() && a != 0.0 && a.abs() <= 360.0 * 3600.0 => FaultKind::Off(a),
                Some(_) => {
                    return Err(format!(
                        "`{s}`: off=ARCSEC takes a finite non-zero angle within a turn, arcsec"
                    ))
                }
                None => {
                    return Err(format!(
                        "`{s}`: expected reject, stall, limit, not-homed, silent or off=ARCSEC"
                    ))
                }
            },
        })
    }
}

impl std::fmt::Display for FaultKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FaultKind::Reject => f.write_str("reject"),
            FaultKind::Stall => f.write_str("stall"),
            FaultKind::Limit => f.write_str("limit"),
            FaultKind::NotHomed => f.write_str("not-homed"),
            FaultKind::Silent => f.write_str("silent"),
            FaultKind::Off(a) => write!(f, "off={a}"),
        }
    }
}

impl FaultKind {
    /// Whether the line protocol's emulated head (`sim:`) can inject it: `reject`, `silent` and
    /// `off=` (the others are a motor controller's warnings, which that protocol has not).
    pub fn applies_to_sim(&self) -> bool {
        matches!(self, FaultKind::Reject | FaultKind::Silent | FaultKind::Off(_))
    }
}

/// Counts the moves a server receives and says which one the fault strikes.
#[derive(Debug, Default)]
pub struct FaultCounter {
    fault: Option<HeadFault>,
    moves: std::sync::atomic::AtomicU64,
}

impl FaultCounter {
    /// A counter for `fault` (None: never strikes).
    pub fn new(fault: Option<HeadFault>) -> FaultCounter {
        FaultCounter { fault, moves: Default::default() }
    }

    /// Counts one move received; its fault, if this is the one struck.
    pub fn next_move(&self) -> Option<FaultKind> {
        let n = self.moves.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        self.fault.filter(|f| f.at_move == n).map(|f| f.kind)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_parse_and_print_and_strike_once() {
        for s in ["reject", "stall", "limit", "not-homed", "silent", "off=36", "off=-7.5"] {
            assert_eq!(s.parse::<FaultKind>().unwrap().to_string(), s);
        }
        for s in ["off=", "off=0", "off=nan", "off=inf", "jam", ""] {
            assert!(s.parse::<FaultKind>().is_err(), "{s}");
        }
        let c = FaultCounter::new(Some(HeadFault { kind: FaultKind::Stall, at_move: 2 }));
        assert_eq!((c.next_move(), c.next_move(), c.next_move()), (None, Some(FaultKind::Stall), None));
        assert!(FaultKind::Off(3.0).applies_to_sim() && !FaultKind::Stall.applies_to_sim());
    }
}
