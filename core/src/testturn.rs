//! The test-turn method on a campaign: find the positions where an axis of the block sees +g and
//! −g, and apply the shared crate's two- or six-position formulas per channel.

use accelcal_shared::terms::MODEL_4;
use accelcal_shared::testturn::{self, SixPositions};

use crate::error::{Classify, Kind};
use crate::lsq::LsqFit;
use crate::positions::{ChannelStats, Positions};

/// Why test turns could not be applied.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TestTurnError {
    /// The plan has no pair of positions 180° apart along any axis.
    #[error("the plan has no pair of positions with an axis along +g and -g (test turns need them; e.g. alpha 0 and 180 at beta 0)")]
    NoPairs,
}

impl Classify for TestTurnError {
    fn kind(&self) -> Kind {
        Kind::BadInput
    }
}

/// The positions used by the test turns: for each axis, the indices of its `+g` and `−g` dwells.
#[derive(Clone, Debug, PartialEq)]
pub struct Pairs {
    /// `pairs[j] = Some((plus, minus))` when both exist for axis j.
    pub pairs: [Option<(usize, usize)>; 3],
}

impl Pairs {
    /// Finds the pairs in the plan.
    pub fn find(pos: &Positions) -> Result<Pairs, TestTurnError> {
        let pairs =
            [0, 1, 2].map(|j| Some((pos.find_axis_position(j, 1.0)?, pos.find_axis_position(j, -1.0)?)));
        if pairs.iter().all(Option::is_none) {
            return Err(TestTurnError::NoPairs);
        }
        Ok(Pairs { pairs })
    }

    /// Every position index the test turns use.
    pub fn used(&self) -> Vec<usize> {
        self.pairs.iter().flatten().flat_map(|&(p, m)| [p, m]).collect()
    }
}

/// Test-turn calibration of one channel as a model-4 fit: `[u0, kx, ky, kz]`. With all six
/// positions the full sensitivity row is determined; with fewer, the axes without a pair get a
/// zero coefficient (one mounting cannot determine them) and a NaN standard error.
pub fn fit(pos: &Positions, ch: &ChannelStats, pairs: &Pairs) -> LsqFit {
    let g = pos.g;
    let mean_var = |p: usize| {
        let n = pos.weight[p];
        if n > 1.0 {
            ch.within_ss[p] / (n - 1.0) / n
        } else {
            f64::NAN
        }
    };
    let mut six = SixPositions { plus: [0.0; 3], minus: [0.0; 3] };
    let mut se = [f64::NAN; 4];
    for j in 0..3 {
        if let Some((p, m)) = pairs.pairs[j] {
            six.plus[j] = ch.mean[p];
            six.minus[j] = ch.mean[m];
            se[j + 1] = (mean_var(p) + mean_var(m)).sqrt() / (2.0 * g);
        }
    }
    // Axes without a pair contribute zero half-difference; the own axis is the largest one found.
    let row = testturn::six_position(&six, g);
    let (p, m) = pairs.pairs[row.own_axis].expect("the own axis has a pair");
    let (u0, _) = testturn::two_position(ch.mean[p], ch.mean[m], g);
    se[0] = (mean_var(p) + mean_var(m)).sqrt() / 2.0;
    // The pairs use disjoint positions, so the sensitivities are uncorrelated; u0 and the own
    // axis's sensitivity share the own pair: Cov((u₊+u₋)/2, (u₊−u₋)/2g) = (var₊ − var₋)/4g.
    let mut covariance = vec![vec![0.0; 4]; 4];
    for (c, s) in se.iter().enumerate() {
        covariance[c][c] = s * s;
    }
    let own = row.own_axis + 1;
    let c0 = (mean_var(p) - mean_var(m)) / (4.0 * g);
    (covariance[0][own], covariance[own][0]) = (c0, c0);
    LsqFit {
        structure: MODEL_4,
        coefficients: vec![u0, row.k[0], row.k[1], row.k[2]],
        covariance,
        condition: 1.0,
        rms: f64::NAN,
        dof: 0.0,
    }
}
