//! Model terms: the polynomial basis in (ax, ay, az) up to degree 3 and the thermal terms in `t`,
//! model structures as term sets, and the paper's eleven candidate models.
//!
//! Canonical names: `1, ax, ay, az, ax^2, ay^2, az^2, ax*ay, ax*az, ay*az`, then the cubic terms in
//! lexicographic order `ax^3, ax^2*ay, ax^2*az, ax*ay^2, ax*ay*az, ax*az^2, ay^3, ay^2*az, ay*az^2,
//! az^3`, then the thermal terms `t, t^2, ax*t, ay*t, az*t`. Variables are ordered
//! ax < ay < az < t, powers are written with `^`, products with `*`.
//!
//! `t` is the temperature relative to the record's reference, `temp_c − t_ref` (°C). The thermal
//! terms are a bias that moves with temperature (`t`, `t^2`) and a sensitivity that does (`ax*t`
//! …): exactly what a node applies as `a = K(t)⁻¹ (u − u0(t))`. The indices of the first 20 terms
//! are those of record format 1 and never change.

use core::fmt;

/// One monomial `ax^px · ay^py · az^pz · t^pt` of [`BASIS`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Term {
    /// Powers of ax, ay, az and t.
    pub pow: [u8; 4],
}

/// Number of terms in the basis: the full cubic in acceleration (20, the intercept included) and
/// the 5 thermal terms.
pub const N_BASIS: usize = 25;

/// Number of terms in acceleration only (the cubic basis); the thermal terms follow.
pub const N_ACCEL_BASIS: usize = 20;

/// Index of `t` in [`BASIS`]: the first thermal term.
pub const T_INDEX: usize = 20;

const fn t(px: u8, py: u8, pz: u8) -> Term {
    Term { pow: [px, py, pz, 0] }
}

const fn th(px: u8, py: u8, pz: u8, pt: u8) -> Term {
    Term { pow: [px, py, pz, pt] }
}

/// The full basis in canonical order; a term's index here is its identity in records and masks.
pub const BASIS: [Term; N_BASIS] = [
    t(0, 0, 0),
    t(1, 0, 0),
    t(0, 1, 0),
    t(0, 0, 1),
    t(2, 0, 0),
    t(0, 2, 0),
    t(0, 0, 2),
    t(1, 1, 0),
    t(1, 0, 1),
    t(0, 1, 1),
    t(3, 0, 0),
    t(2, 1, 0),
    t(2, 0, 1),
    t(1, 2, 0),
    t(1, 1, 1),
    t(1, 0, 2),
    t(0, 3, 0),
    t(0, 2, 1),
    t(0, 1, 2),
    t(0, 0, 3),
    th(0, 0, 0, 1),
    th(0, 0, 0, 2),
    th(1, 0, 0, 1),
    th(0, 1, 0, 1),
    th(0, 0, 1, 1),
];

const VAR: [&str; 4] = ["ax", "ay", "az", "t"];

impl Term {
    /// Total degree of the monomial in acceleration (the power of `t` not counted).
    pub fn degree(self) -> u8 {
        self.pow[0] + self.pow[1] + self.pow[2]
    }

    /// Whether the term holds the temperature `t`.
    pub fn is_thermal(self) -> bool {
        self.pow[3] > 0
    }

    /// Index of this term in [`BASIS`], or `None` when it is not in the basis.
    pub fn index(self) -> Option<usize> {
        BASIS.iter().position(|&b| b == self)
    }

    /// Value of the monomial at `x = [ax, ay, az, t]` (m/s², and °C relative to the reference).
    pub fn eval(self, x: [f64; 4]) -> f64 {
        let mut v = 1.0;
        for (i, &p) in self.pow.iter().enumerate() {
            for _ in 0..p {
                v *= x[i];
            }
        }
        v
    }

    /// Parses a term name such as `1`, `ax`, `ax^2`, `ax*ay`, `ax^2*az`, `t` or `ax*t`. Factors
    /// may come in any order and repeat (`ay*ax` is `ax*ay`); the degree in acceleration must not
    /// exceed 3, and a term in `t` must be one of the thermal terms of [`BASIS`].
    pub fn parse(s: &str) -> Result<Term, TermError> {
        let s = s.trim();
        if s == "1" {
            return Ok(t(0, 0, 0));
        }
        if s.is_empty() {
            return Err(TermError::Empty);
        }
        let mut pow = [0u8; 4];
        for factor in s.split('*') {
            let factor = factor.trim();
            let (var, p) = match factor.split_once('^') {
                Some((v, p)) => {
                    let p: u8 = p.trim().parse().map_err(|_| TermError::BadPower)?;
                    (v.trim(), p)
                }
                None => (factor, 1),
            };
            let i = VAR.iter().position(|&n| n == var).ok_or(TermError::UnknownVariable)?;
            if p == 0 || p > 3 {
                return Err(TermError::BadPower);
            }
            pow[i] = pow[i].saturating_add(p);
        }
        let term = Term { pow };
        if term.degree() > 3 {
            return Err(TermError::DegreeTooHigh);
        }
        if term.index().is_none() {
            return Err(TermError::NotThermalTerm);
        }
        Ok(term)
    }
}

impl fmt::Display for Term {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.pow == [0; 4] {
            return f.write_str("1");
        }
        let mut first = true;
        for (i, &p) in self.pow.iter().enumerate() {
            if p == 0 {
                continue;
            }
            if !first {
                f.write_str("*")?;
            }
            first = false;
            f.write_str(VAR[i])?;
            if p > 1 {
                write!(f, "^{p}")?;
            }
        }
        Ok(())
    }
}

/// Why a term name did not parse.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TermError {
    /// The name is empty.
    Empty,
    /// A factor is not `ax`, `ay`, `az` or `t`.
    UnknownVariable,
    /// A power is not 1, 2 or 3.
    BadPower,
    /// The total degree in acceleration exceeds 3.
    DegreeTooHigh,
    /// A term in `t` other than `t, t^2, ax*t, ay*t, az*t`.
    NotThermalTerm,
}

impl fmt::Display for TermError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            TermError::Empty => "empty term name",
            TermError::UnknownVariable => "unknown variable (expected ax, ay, az or t)",
            TermError::BadPower => "bad power (expected 1, 2 or 3)",
            TermError::DegreeTooHigh => "degree above 3",
            TermError::NotThermalTerm => "the terms in t are t, t^2, ax*t, ay*t and az*t",
        })
    }
}

#[cfg(feature = "std")]
impl std::error::Error for TermError {}

/// A model structure: a set of basis terms, always containing the intercept `1`.
///
/// Stored as a bit mask over [`BASIS`] indices (bit 0 is the intercept).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Structure(u32);

impl Structure {
    /// The intercept-only model.
    pub const INTERCEPT: Structure = Structure(1);

    /// A structure from a bit mask over [`BASIS`]; the intercept bit is always set and bits beyond
    /// the basis are dropped.
    pub const fn from_mask(mask: u32) -> Structure {
        Structure((mask | 1) & ((1 << N_BASIS) - 1))
    }

    /// A structure from term indices into [`BASIS`] (the intercept is added). Indices beyond the
    /// basis are ignored.
    pub const fn from_indices(idx: &[usize]) -> Structure {
        let mut m = 1u32;
        let mut i = 0;
        while i < idx.len() {
            if idx[i] < N_BASIS {
                m |= 1 << idx[i];
            }
            i += 1;
        }
        Structure(m)
    }

    /// The bit mask over [`BASIS`].
    pub const fn mask(self) -> u32 {
        self.0
    }

    /// Number of terms, the intercept included.
    pub const fn len(self) -> usize {
        self.0.count_ones() as usize
    }

    /// Never true: every structure holds the intercept.
    pub const fn is_empty(self) -> bool {
        false
    }

    /// Whether the structure holds basis term `i`.
    pub const fn contains(self, i: usize) -> bool {
        i < N_BASIS && self.0 & (1 << i) != 0
    }

    /// The thermal terms (`t`, `t^2`, `ax*t`, `ay*t`, `az*t`) as a mask over [`BASIS`].
    pub const THERMAL_MASK: u32 = 0b11111 << T_INDEX;

    /// Whether the structure holds a term in `t`.
    pub const fn is_thermal(self) -> bool {
        self.0 & Self::THERMAL_MASK != 0
    }

    /// The structure without its thermal terms.
    pub const fn without_thermal(self) -> Structure {
        Structure(self.0 & !Self::THERMAL_MASK)
    }

    /// Highest degree in acceleration among the terms.
    pub fn degree(self) -> u8 {
        self.terms().map(Term::degree).max().unwrap_or(0)
    }

    /// The basis indices of the terms, in canonical order.
    pub fn indices(self) -> impl Iterator<Item = usize> {
        (0..N_BASIS).filter(move |&i| self.0 & (1 << i) != 0)
    }

    /// The terms, in canonical order.
    pub fn terms(self) -> impl Iterator<Item = Term> {
        self.indices().map(|i| BASIS[i])
    }

    /// Whether every term of `self` is in `other`.
    pub const fn is_subset_of(self, other: Structure) -> bool {
        self.0 & !other.0 == 0
    }
}

impl fmt::Display for Structure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (n, term) in self.terms().enumerate() {
            if n > 0 {
                f.write_str(",")?;
            }
            write!(f, "{term}")?;
        }
        Ok(())
    }
}

/// The linear model `1, ax, ay, az`: the paper's model 4, applied by the firmware.
pub const MODEL_4: Structure = Structure::from_indices(&[1, 2, 3]);

/// The paper's eleven candidate models (Table 1), in the paper's order (model 1 first).
pub const PAPER_MODELS: [Structure; 11] = [
    Structure::from_indices(&[3]),
    Structure::from_indices(&[2, 3]),
    Structure::from_indices(&[1, 3]),
    Structure::from_indices(&[1, 2, 3]),
    Structure::from_indices(&[1, 2, 3, 4]),
    Structure::from_indices(&[1, 2, 3, 4, 7]),
    Structure::from_indices(&[1, 2, 3, 7]),
    Structure::from_indices(&[1, 2, 3, 4, 5]),
    Structure::from_indices(&[1, 2, 3, 7, 5]),
    Structure::from_indices(&[1, 2, 3, 4, 7, 5]),
    Structure::from_indices(&[1, 2, 3, 4, 5, 6, 7, 8, 9]),
];

/// The basis over which GMDH enumerates candidate structures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Basis {
    /// The paper's eleven models only.
    Paper,
    /// `1, ax, ay, az`: every subset holding the intercept (8 models).
    Linear,
    /// Terms up to degree 2 (10 terms, 512 models).
    Quadratic,
    /// Terms up to degree 3 (20 terms, 524,288 models).
    Cubic,
    /// `1, ax, ay, az` with the thermal terms `t, t^2, ax*t, ay*t, az*t` (9 terms, 256 models).
    LinearThermal,
    /// Terms up to degree 2 with the thermal terms (15 terms, 16,384 models).
    QuadraticThermal,
}

impl Basis {
    /// The union of all terms the basis may use.
    pub const fn full(self) -> Structure {
        match self {
            Basis::Linear => Structure::from_mask(0b1111),
            Basis::Paper | Basis::Quadratic => Structure::from_mask((1 << 10) - 1),
            Basis::Cubic => Structure::from_mask((1 << 20) - 1),
            Basis::LinearThermal => Structure::from_mask(0b1111 | Structure::THERMAL_MASK),
            Basis::QuadraticThermal => Structure::from_mask(((1 << 10) - 1) | Structure::THERMAL_MASK),
        }
    }

    /// Whether the basis holds terms in `t` (and so needs a temperature).
    pub const fn is_thermal(self) -> bool {
        matches!(self, Basis::LinearThermal | Basis::QuadraticThermal)
    }

    /// Number of candidate structures the basis enumerates.
    pub const fn candidate_count(self) -> usize {
        match self {
            Basis::Paper => PAPER_MODELS.len(),
            _ => 1 << (self.full().len() - 1),
        }
    }

    /// The `n`-th candidate structure (`n < candidate_count()`). For the polynomial bases, the
    /// candidates are all subsets of the non-intercept terms, each with the intercept: bit `j` of
    /// `n` stands for the `j`-th non-intercept term of [`Basis::full`] in canonical order.
    pub fn candidate(self, n: usize) -> Structure {
        match self {
            Basis::Paper => PAPER_MODELS[n % PAPER_MODELS.len()],
            Basis::Linear | Basis::Quadratic | Basis::Cubic => {
                let k = self.full().len() - 1;
                let sub = (n as u32) & ((1u32 << k) - 1);
                Structure::from_mask(sub << 1)
            }
            Basis::LinearThermal | Basis::QuadraticThermal => {
                let mut mask = 1u32;
                for (j, i) in self.full().indices().skip(1).enumerate() {
                    if n >> j & 1 == 1 {
                        mask |= 1 << i;
                    }
                }
                Structure::from_mask(mask)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    extern crate std;
    use std::string::ToString;

    #[test]
    fn canonical_names_round_trip() {
        let names: std::vec::Vec<_> = BASIS.iter().map(|t| t.to_string()).collect();
        assert_eq!(
            names,
            [
                "1", "ax", "ay", "az", "ax^2", "ay^2", "az^2", "ax*ay", "ax*az", "ay*az", "ax^3", "ax^2*ay",
                "ax^2*az", "ax*ay^2", "ax*ay*az", "ax*az^2", "ay^3", "ay^2*az", "ay*az^2", "az^3", "t",
                "t^2", "ax*t", "ay*t", "az*t"
            ]
        );
        for (i, n) in names.iter().enumerate() {
            assert_eq!(Term::parse(n).unwrap().index(), Some(i));
        }
    }

    #[test]
    fn parse_accepts_any_factor_order_and_rejects_bad_names() {
        assert_eq!(Term::parse("ay*ax").unwrap(), BASIS[7]);
        assert_eq!(Term::parse("az * ax*ax").unwrap(), BASIS[12]);
        assert_eq!(Term::parse("ax^4"), Err(TermError::BadPower));
        assert_eq!(Term::parse("ax^2*ay^2"), Err(TermError::DegreeTooHigh));
        assert_eq!(Term::parse("bx"), Err(TermError::UnknownVariable));
        assert_eq!(Term::parse(""), Err(TermError::Empty));
        assert_eq!(Term::parse("t*az").unwrap(), BASIS[24]);
        assert_eq!(Term::parse("t^3"), Err(TermError::NotThermalTerm));
        assert_eq!(Term::parse("ax^2*t"), Err(TermError::NotThermalTerm));
        assert_eq!(Term::parse("ax*ay*t"), Err(TermError::NotThermalTerm));
    }

    #[test]
    fn eval_and_structures() {
        assert_eq!(Term::parse("ax^2*az").unwrap().eval([2.0, 3.0, 5.0, 7.0]), 20.0);
        assert_eq!(Term::parse("ay*t").unwrap().eval([2.0, 3.0, 5.0, 7.0]), 21.0);
        assert_eq!(MODEL_4.to_string(), "1,ax,ay,az");
        assert_eq!(PAPER_MODELS[3], MODEL_4);
        assert_eq!(PAPER_MODELS[10].len(), 10);
        assert_eq!(PAPER_MODELS[8].to_string(), "1,ax,ay,az,ay^2,ax*ay");
        assert_eq!(Basis::Cubic.candidate_count(), 524_288);
        assert_eq!(Basis::Linear.candidate(7), MODEL_4);
        assert!(MODEL_4.is_subset_of(PAPER_MODELS[10]));
        assert_eq!(Basis::LinearThermal.candidate_count(), 256);
        assert_eq!(Basis::QuadraticThermal.candidate_count(), 16_384);
        assert_eq!(Basis::LinearThermal.candidate(0b1000_0111).to_string(), "1,ax,ay,az,az*t");
        assert_eq!(Basis::QuadraticThermal.candidate(1 << 9).to_string(), "1,t");
        assert_eq!(Basis::QuadraticThermal.candidate(1 << 13).to_string(), "1,az*t");
        assert!(!MODEL_4.is_thermal());
        assert!(Basis::LinearThermal.full().is_thermal());
        assert_eq!(Basis::LinearThermal.full().without_thermal(), MODEL_4);
    }
}
