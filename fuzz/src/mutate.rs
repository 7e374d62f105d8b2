//! Generic byte-string mutations: bit flips, byte overwrites with random and boundary values,
//! insertions, deletions, duplications, truncation, splicing with another seed, and fully random
//! strings. No coverage feedback decides which ones to keep: every input starts again from a seed.

use crate::rng::Rng;

/// Byte values that sit on the edges of the formats' checks (COBS delimiter and run codes,
/// varint continuation bits, small counts, erased flash).
const INTERESTING: [u8; 10] = [0x00, 0x01, 0x02, 0x03, 0x10, 0x7f, 0x80, 0xfe, 0xff, 0x14];

/// Longest input the mutations grow a string to.
pub const MAX_INPUT: usize = 4096;

/// Applies one to eight random mutations to `data`; `other` is a second seed for splicing.
pub fn mutate(rng: &mut Rng, data: &mut Vec<u8>, other: &[u8]) {
    let rounds = 1 + rng.below(8);
    for _ in 0..rounds {
        mutate_once(rng, data, other);
    }
    data.truncate(MAX_INPUT);
}

fn mutate_once(rng: &mut Rng, data: &mut Vec<u8>, other: &[u8]) {
    let len = data.len();
    match rng.below(10) {
        0 | 1 if len > 0 => {
            let i = rng.below(len * 8);
            data[i / 8] ^= 1 << (i % 8);
        }
        2 if len > 0 => {
            let i = rng.below(len);
            data[i] = rng.byte();
        }
        3 if len > 0 => {
            let i = rng.below(len);
            data[i] = INTERESTING[rng.below(INTERESTING.len())];
        }
        4 => {
            let at = rng.below(len + 1);
            let n = 1 + rng.below(16);
            let bytes: Vec<u8> = (0..n).map(|_| rng.byte()).collect();
            data.splice(at..at, bytes);
        }
        5 if len > 0 => {
            let at = rng.below(len);
            let n = 1 + rng.below((len - at).min(32));
            data.drain(at..at + n);
        }
        6 if len > 0 => {
            let at = rng.below(len);
            let n = 1 + rng.below((len - at).min(64));
            let copy = data[at..at + n].to_vec();
            let to = rng.below(len + 1);
            data.splice(to..to, copy);
        }
        7 if len > 0 => data.truncate(rng.below(len)),
        8 if !other.is_empty() => {
            // Splice: a prefix of this input and a suffix of the other seed.
            let cut = rng.below(len + 1);
            let from = rng.below(other.len());
            data.truncate(cut);
            data.extend_from_slice(&other[from..]);
        }
        9 if rng.one_in(8) => {
            let n = rng.below(600);
            *data = (0..n).map(|_| rng.byte()).collect();
        }
        _ => {
            let at = rng.below(len + 1);
            data.insert(at, INTERESTING[rng.below(INTERESTING.len())]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mutations_change_inputs_and_respect_the_size_limit() {
        let mut rng = Rng::new(1);
        let seed: Vec<u8> = (0..=255).collect();
        let mut changed = 0;
        for _ in 0..10_000 {
            let mut d = seed.clone();
            mutate(&mut rng, &mut d, &seed[..100]);
            assert!(d.len() <= MAX_INPUT);
            changed += (d != seed) as usize;
        }
        assert!(changed > 9_500, "{changed}");
    }

    #[test]
    fn same_seed_same_mutations() {
        let (mut a, mut b) = (Rng::new(7), Rng::new(7));
        let (mut x, mut y) = (vec![1u8; 50], vec![1u8; 50]);
        for _ in 0..100 {
            mutate(&mut a, &mut x, &[9, 9]);
            mutate(&mut b, &mut y, &[9, 9]);
        }
        assert_eq!(x, y);
    }
}
