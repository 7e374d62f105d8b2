//! The effect registry: every unmodelled effect the simulator can add and the diagnosis can name,
//! defined once. Its name (an interface: `simulate --effect NAME=...`, the diagnosis's JSON and
//! tables), its parameters with their units and defaults, and its help text come from here; the
//! simulator ([`crate::sim::effects`]) builds its models from these keys, the diagnosis
//! ([`crate::diagnose`]) reports its estimates with these names and units, and the command line
//! prints this help.

/// An effect of the library.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectKind {
    /// Output drifting linearly with time.
    BiasDrift,
    /// Bias and scale depending on `temp_c`.
    Temperature,
    /// Second-order terms of the input acceleration.
    Nonlinearity,
    /// Constant rotation between the head's stages.
    HeadMisalignment,
    /// Output depending on the direction of approach.
    Hysteresis,
    /// Transient after each rotation.
    Settling,
    /// Random per-position angle errors.
    AngleError,
}

/// One parameter of an effect.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Param {
    /// Key, as in `simulate --effect NAME=KEY:VALUE` and in the diagnosis's JSON.
    pub key: &'static str,
    /// Unit.
    pub unit: &'static str,
    /// Value when the key is not given to the simulator.
    pub default: f64,
    /// What it is.
    pub meaning: &'static str,
}

/// The definition of an effect.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EffectSpec {
    /// The effect.
    pub kind: EffectKind,
    /// Interface name.
    pub name: &'static str,
    /// Short name for narrow table columns.
    pub short: &'static str,
    /// One line on what it is.
    pub summary: &'static str,
    /// Parameters of the simulator (the diagnosis estimates the same quantities, see
    /// [`unit_of`] for the ones only the diagnosis reports).
    pub params: &'static [Param],
}

const fn p(key: &'static str, unit: &'static str, default: f64, meaning: &'static str) -> Param {
    Param { key, unit, default, meaning }
}

/// Unit of the nonlinearity coefficients of degree-2 terms.
pub const NONLINEARITY_UNIT: &str = "codes/(m/s²)²";

/// Every effect, in the order the diagnosis lists them.
pub const REGISTRY: [EffectSpec; 7] = [
    EffectSpec {
        kind: EffectKind::BiasDrift,
        name: "bias_drift",
        short: "drift",
        summary: "output drifting linearly with time",
        params: &[p("rate", "codes/s", 0.0, "drift rate")],
    },
    EffectSpec {
        kind: EffectKind::Temperature,
        name: "temperature",
        short: "temp",
        summary: "bias and scale factor depending on temp_c (needs a temperature column, or the simulator's temperature profile)",
        params: &[
            p("bias", "codes/°C", 0.0, "bias coefficient"),
            p("scale", "ppm/°C", 0.0, "scale-factor coefficient, of the linear signal"),
            p("t_ref", "°C", 25.0, "reference temperature"),
        ],
    },
    EffectSpec {
        kind: EffectKind::Nonlinearity,
        name: "nonlinearity",
        short: "nonlin",
        summary: "second-order terms of the input: k2 on the sensitive axis, or any basis term such as ax*ay",
        params: &[p("k2", NONLINEARITY_UNIT, 0.0, "coefficient of the squared sensitive-axis acceleration")],
    },
    EffectSpec {
        kind: EffectKind::HeadMisalignment,
        name: "head_misalignment",
        short: "headmis",
        summary: "constant rotation between the alpha and beta stages of the head",
        params: &[
            p("rx_mrad", "mrad", 0.0, "rotation about x"),
            p("ry_mrad", "mrad", 0.0, "rotation about y"),
            p("rz_mrad", "mrad", 0.0, "rotation about z"),
        ],
    },
    EffectSpec {
        kind: EffectKind::Hysteresis,
        name: "hysteresis",
        short: "hyst",
        summary: "output offset by the direction of approach of the sensitive-axis input",
        params: &[p("h", "codes", 0.0, "offset times the sign of the input's change")],
    },
    EffectSpec {
        kind: EffectKind::Settling,
        name: "settling",
        short: "settle",
        summary: "exponential transient after each rotation",
        params: &[
            p("gain", "codes/(m/s²)", 0.0, "amplitude per m/s² of sensitive-axis step"),
            p("tau", "s", 0.5, "time constant (> 0)"),
        ],
    },
    EffectSpec {
        kind: EffectKind::AngleError,
        name: "angle_error",
        short: "angle",
        summary: "random setting error of the head's angles, drawn per position",
        params: &[p("sd_mrad", "mrad", 0.0, "one-sigma error of alpha and of beta")],
    },
];

impl EffectKind {
    /// Every effect, in registry order.
    pub const ALL: [EffectKind; 7] = [
        EffectKind::BiasDrift,
        EffectKind::Temperature,
        EffectKind::Nonlinearity,
        EffectKind::HeadMisalignment,
        EffectKind::Hysteresis,
        EffectKind::Settling,
        EffectKind::AngleError,
    ];

    /// Its definition.
    pub fn spec(self) -> &'static EffectSpec {
        &REGISTRY[self as usize]
    }

    /// The interface name.
    pub fn name(self) -> &'static str {
        self.spec().name
    }

    /// The effect with this interface name.
    pub fn from_name(name: &str) -> Option<EffectKind> {
        REGISTRY.iter().find(|s| s.name == name).map(|s| s.kind)
    }
}

/// Every interface name, in registry order.
pub fn names() -> impl Iterator<Item = &'static str> {
    REGISTRY.iter().map(|s| s.name)
}

/// The short name of an effect name (the name itself when it is not one).
pub fn short_name(name: &str) -> &str {
    REGISTRY.iter().find(|s| s.name == name).map_or(name, |s| s.short)
}

/// Unit of a parameter an effect reports: its simulator parameters, the nonlinearity's basis
/// terms (degree 2 in the diagnosis), and the diagnosis's fitted settling time constant `tau_s`.
pub fn unit_of(kind: EffectKind, key: &str) -> Option<&'static str> {
    if let Some(p) = kind.spec().params.iter().find(|p| p.key == key) {
        return Some(p.unit);
    }
    match (kind, key) {
        (EffectKind::Settling, "tau_s") => Some("s"),
        (EffectKind::Nonlinearity, k) if accelcal_shared::Term::parse(k).is_ok_and(|t| t.degree() == 2) => {
            Some(NONLINEARITY_UNIT)
        }
        _ => None,
    }
}

/// The help text of `simulate --effect`: every effect with its keys, units and defaults.
pub fn help_text() -> String {
    let mut s = String::from(
        "Add an error effect, `NAME=KEY:VALUE,...` (repeatable; a key left out takes its default). Effects:",
    );
    for e in &REGISTRY {
        let keys: Vec<String> =
            e.params.iter().map(|p| format!("{}:{} {} [{}]", p.key, p.meaning, p.unit, p.default)).collect();
        s.push_str(&format!("\n  {}: {}; {}", e.name, e.summary, keys.join(", ")));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_registry_is_in_enum_order_with_unique_names() {
        for (i, e) in REGISTRY.iter().enumerate() {
            assert_eq!(e.kind as usize, i, "{}", e.name);
            assert_eq!(EffectKind::from_name(e.name), Some(e.kind));
            assert_eq!(REGISTRY.iter().filter(|o| o.name == e.name || o.short == e.short).count(), 1);
            assert!(e.params.iter().all(|p| !p.unit.is_empty()), "{}", e.name);
        }
        assert_eq!(EffectKind::from_name("wobble"), None);
    }

    #[test]
    fn every_reported_parameter_has_a_unit() {
        assert_eq!(unit_of(EffectKind::BiasDrift, "rate"), Some("codes/s"));
        assert_eq!(unit_of(EffectKind::Nonlinearity, "ax*ay"), Some(NONLINEARITY_UNIT));
        assert_eq!(unit_of(EffectKind::Settling, "tau_s"), Some("s"));
        assert_eq!(unit_of(EffectKind::Hysteresis, "tau_s"), None);
        let help = help_text();
        for e in &REGISTRY {
            assert!(help.contains(e.name), "{help}");
        }
    }
}
