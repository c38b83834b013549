//! Hamming dictionaries of marker codes (spec 3.2): generation, the checked-in paper
//! dictionary, and lookup with error correction and orientation.
//!
//! Every pair of codes differs in at least `d_min` bits under every rotation that maps the
//! grid onto itself, and every code is at least `d_min` from its own non-trivial rotations.
//! A read code is accepted as the entry at Hamming distance `< d_min / 2`, i.e. at most
//! `(d_min - 1) / 2` bits; with `d_min = 6` two flipped bits are corrected and three can
//! never produce a wrong ID (they are at least 3 bits from every other entry too). Because
//! rotations are included, the match also says how the marker was turned.
//!
//! Generation ([`Dictionary::generate`]) is a deterministic greedy search: the `2^bits`
//! candidate codes are visited in a fixed pseudo-random order (an integer bijection, the
//! same on every platform), candidates near all-black or all-white or with too few
//! black/white transitions are skipped (thresholds in [`GenerateParams`]), and a candidate
//! is kept if it is far enough from its own rotations and from every kept code's rotations.
//! The result for the paper's family is checked in as `data/dict-4x5-d6.txt`
//! (regenerate with `cargo xtask dictionary`; a test checks that it is reproduced exactly).

use std::sync::OnceLock;

use crate::error::FiducialError;
use crate::family::MarkerFamily;

/// The checked-in text of the paper's dictionary (4 x 5 cells, `d_min = 6`).
pub(crate) const PAPER_DICTIONARY_TEXT: &str = include_str!("../data/dict-4x5-d6.txt");

/// The name of the paper's (our own) dictionary, as [`Dictionary::name`] and the CLI give it.
pub const PAPER_NAME: &str = "FORMATION_4X5";

/// Parameters of [`Dictionary::generate`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GenerateParams {
    /// The grid of data cells.
    pub family: MarkerFamily,
    /// Minimum Hamming distance over every pair and rotation.
    pub min_distance: u32,
    /// Fewest black data cells a code may have (keeps codes away from all-white).
    pub min_black: u32,
    /// Most black data cells a code may have (keeps codes away from all-black).
    pub max_black: u32,
    /// Fewest black/white transitions between edge-adjacent data cells (avoids large blobs,
    /// which look like the border or like background).
    pub min_transitions: u32,
    /// Stop once this many codes are kept.
    pub max_codes: usize,
    /// Stop after visiting this many candidates (matters only for large families).
    pub max_candidates: u64,
    /// Seed of the candidate order.
    pub seed: u64,
}

impl GenerateParams {
    /// Default thresholds for a family: black cells in `[ceil(bits/4), bits - ceil(bits/4)]`,
    /// at least `ceil(pairs / 3)` transitions (pairs = edge-adjacent data-cell pairs), at
    /// most 100 codes, at most `2^24` candidates, seed 0.
    pub fn for_family(family: MarkerFamily, min_distance: u32) -> Self {
        let bits = family.bits();
        let quarter = bits.div_ceil(4);
        Self {
            family,
            min_distance,
            min_black: quarter,
            max_black: bits - quarter,
            min_transitions: family.adjacent_pairs().div_ceil(3),
            max_codes: 100,
            max_candidates: 1 << 24,
            seed: 0,
        }
    }

    /// The parameters of the checked-in paper dictionary: 4 x 5 cells, `d_min = 6`,
    /// 5..=15 black cells, at least 11 of the 31 possible transitions, up to 100 codes.
    pub fn paper() -> Self {
        Self::for_family(MarkerFamily::PAPER_4X5, 6)
    }
}

/// A dictionary entry found by [`Dictionary::lookup`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Match {
    /// Index of the entry in the dictionary.
    pub index: usize,
    /// The entry's code (in the marker's own orientation).
    pub code: u64,
    /// Bits in which the read code differs from the (rotated) entry.
    pub distance: u32,
    /// Clockwise quarter turns by which the read grid shows the marker: the read code is
    /// closest to `family.rotate(code, rotation)`.
    pub rotation: u8,
}

/// A set of codes with a guaranteed minimum Hamming distance over rotations.
///
/// Lookup does not scan the codes: every code under every rotation is kept in a sorted
/// table, so an exact read is a binary search, and a read with `t` bit errors is found by
/// searching the read with each set of at most `t` bits flipped (when there are fewer such
/// sets than table entries; a scan otherwise).
#[derive(Debug, Clone)]
pub struct Dictionary {
    family: MarkerFamily,
    min_distance: u32,
    codes: Vec<u64>,
    /// `rotated[i][q]` = code `i` turned `q` clockwise quarter turns (unused slots for a
    /// non-square family hold the code itself and are never read).
    rotated: Vec<[u64; 4]>,
    /// Most bit errors a lookup corrects ([`Dictionary::max_correctable`]).
    correction: u32,
    /// The standard name, for the paper's and the predefined dictionaries.
    name: Option<&'static str>,
    /// Whether markers of this dictionary are printed inside a white quiet zone that the
    /// decoder may use as its white reference.
    quiet_zone: bool,
    /// `(code turned q, index * 4 + q)` for every entry and symmetry, sorted; of equal
    /// codes only the lowest `index * 4 + q` is kept.
    table: Vec<(u64, u32)>,
}

impl PartialEq for Dictionary {
    /// Same family, codes, distance, correction and white reference; the name is a label
    /// and does not take part (a regenerated paper dictionary equals [`Dictionary::paper`]).
    fn eq(&self, other: &Self) -> bool {
        self.family == other.family
            && self.min_distance == other.min_distance
            && self.codes == other.codes
            && self.correction == other.correction
            && self.quiet_zone == other.quiet_zone
    }
}

impl Eq for Dictionary {}

/// The sorted lookup table of [`Dictionary`].
fn lookup_table(family: MarkerFamily, rotated: &[[u64; 4]]) -> Vec<(u64, u32)> {
    let sym = family.symmetries();
    let mut table = Vec::with_capacity(rotated.len() * sym.len());
    for (i, r) in rotated.iter().enumerate() {
        for &q in sym {
            table.push((r[q as usize], (i as u32) << 2 | u32::from(q)));
        }
    }
    table.sort_unstable();
    table.dedup_by_key(|e| e.0);
    table
}

/// `n choose k`, saturating.
fn choose(n: u32, k: u32) -> u64 {
    (0..k).fold(1u64, |acc, i| {
        acc.saturating_mul(u64::from(n - i)) / u64::from(i + 1)
    })
}

/// Hamming distance of two codes.
#[inline]
pub fn hamming(a: u64, b: u64) -> u32 {
    (a ^ b).count_ones()
}

impl Dictionary {
    /// The paper's dictionary (4 x 5 cells, `d_min = 6`), parsed once from the checked-in
    /// `data/dict-4x5-d6.txt`.
    pub fn paper() -> &'static Dictionary {
        static PAPER: OnceLock<Dictionary> = OnceLock::new();
        PAPER.get_or_init(|| {
            // The embedded text is generated by `cargo xtask dictionary` and checked by the
            // crate's tests (parse + exact regeneration), so this cannot fail at run time.
            Dictionary::from_text(PAPER_DICTIONARY_TEXT)
                .expect("embedded data/dict-4x5-d6.txt is valid (checked by tests)")
                .named(PAPER_NAME)
        })
    }

    /// A dictionary from explicit codes, checking every distance constraint.
    pub fn new(
        family: MarkerFamily,
        min_distance: u32,
        codes: Vec<u64>,
    ) -> Result<Self, FiducialError> {
        if min_distance == 0 || min_distance > family.bits() {
            return Err(FiducialError::BadMinDistance {
                min_distance,
                bits: family.bits(),
            });
        }
        if codes.is_empty() {
            return Err(FiducialError::EmptyDictionary);
        }
        let mut rotated = Vec::with_capacity(codes.len());
        for &code in &codes {
            family.check_code(code)?;
            let mut r = [code; 4];
            for &q in family.symmetries() {
                r[q as usize] = family.rotate_unchecked(code, q);
            }
            rotated.push(r);
        }
        for (i, ri) in rotated.iter().enumerate() {
            for &q in &family.symmetries()[1..] {
                let d = hamming(ri[0], ri[q as usize]);
                if d < min_distance {
                    return Err(FiducialError::TooClose {
                        first: i,
                        second: i,
                        quarter_turns: q,
                        distance: d,
                        min_distance,
                    });
                }
            }
            for (j, rj) in rotated.iter().enumerate().skip(i + 1) {
                for &q in family.symmetries() {
                    let d = hamming(ri[0], rj[q as usize]);
                    if d < min_distance {
                        return Err(FiducialError::TooClose {
                            first: i,
                            second: j,
                            quarter_turns: q,
                            distance: d,
                            min_distance,
                        });
                    }
                }
            }
        }
        let table = lookup_table(family, &rotated);
        Ok(Self {
            family,
            min_distance,
            codes,
            rotated,
            correction: (min_distance - 1) / 2,
            name: None,
            quiet_zone: true,
            table,
        })
    }

    /// A predefined dictionary from its checked-in table: `min_distance` is the table's
    /// (generated and checked by tests, possibly 0 when two ids coincide up to rotation),
    /// `correction` the default number of bits to correct.
    pub(crate) fn from_standard(
        name: &'static str,
        family: MarkerFamily,
        codes: Vec<u64>,
        min_distance: u32,
        correction: u32,
    ) -> Result<Self, FiducialError> {
        if codes.is_empty() {
            return Err(FiducialError::EmptyDictionary);
        }
        let mut rotated = Vec::with_capacity(codes.len());
        for &code in &codes {
            family.check_code(code)?;
            let mut r = [code; 4];
            for &q in family.symmetries() {
                r[q as usize] = family.rotate_unchecked(code, q);
            }
            rotated.push(r);
        }
        let table = lookup_table(family, &rotated);
        Ok(Self {
            family,
            min_distance,
            codes,
            rotated,
            correction: correction.min(min_distance.saturating_sub(1) / 2),
            name: Some(name),
            quiet_zone: false,
            table,
        })
    }

    /// This dictionary with at most `bits` bit errors corrected by lookups (capped at
    /// `(d_min - 1) / 2`, so a corrected read is still the unique entry that close).
    #[must_use]
    pub fn with_correction(mut self, bits: u32) -> Self {
        self.correction = bits.min(self.min_distance.saturating_sub(1) / 2);
        self
    }

    /// The dictionary's standard name (`FORMATION_4X5` for the paper's, the OpenCV name for
    /// a predefined one), or `None` for a generated or custom one.
    pub fn name(&self) -> Option<&'static str> {
        self.name
    }

    /// This dictionary under a standard name (used for the paper's dictionary).
    pub(crate) fn named(mut self, name: &'static str) -> Self {
        self.name = Some(name);
        self
    }

    /// Whether the decoder takes its white reference from a white quiet zone around the
    /// border (the paper's markers: yes), or from the marker's own white cells (the
    /// predefined ArUco and AprilTag families, which may be printed without one).
    pub fn uses_quiet_zone(&self) -> bool {
        self.quiet_zone
    }

    /// This dictionary with the white reference taken from the quiet zone (`true`) or from
    /// the marker's own white cells (`false`); see [`Dictionary::uses_quiet_zone`].
    #[must_use]
    pub fn with_quiet_zone(mut self, quiet_zone: bool) -> Self {
        self.quiet_zone = quiet_zone;
        self
    }

    /// The entry and rotation whose code is exactly `read`, if any.
    #[inline]
    fn exact(&self, read: u64) -> Option<Match> {
        let i = self.table.partition_point(|e| e.0 < read);
        let &(code, key) = self.table.get(i)?;
        (code == read).then(|| {
            let index = (key >> 2) as usize;
            Match {
                index,
                code: self.codes[index],
                distance: 0,
                rotation: (key & 3) as u8,
            }
        })
    }

    /// Generates a dictionary deterministically (see the module docs for the method).
    pub fn generate(params: &GenerateParams) -> Result<Self, FiducialError> {
        let family = params.family;
        let bits = family.bits();
        if params.min_distance == 0 || params.min_distance > bits {
            return Err(FiducialError::BadMinDistance {
                min_distance: params.min_distance,
                bits,
            });
        }
        let sym = family.symmetries();
        let total = if bits >= 64 { u64::MAX } else { 1u64 << bits };
        let visits = total.min(params.max_candidates);
        let mut kept: Vec<[u64; 4]> = Vec::new();
        let mut codes = Vec::new();
        for i in 0..visits {
            if codes.len() >= params.max_codes {
                break;
            }
            let c = permute(i, bits, params.seed);
            let black = c.count_ones();
            if black < params.min_black
                || black > params.max_black
                || family.transitions(c) < params.min_transitions
            {
                continue;
            }
            let mut r = [c; 4];
            for &q in sym {
                r[q as usize] = family.rotate_unchecked(c, q);
            }
            if sym[1..]
                .iter()
                .any(|&q| hamming(c, r[q as usize]) < params.min_distance)
            {
                continue;
            }
            let far = kept.iter().all(|k| {
                sym.iter()
                    .all(|&q| hamming(c, k[q as usize]) >= params.min_distance)
            });
            if far {
                kept.push(r);
                codes.push(c);
            }
        }
        Self::new(family, params.min_distance, codes)
    }

    /// The family of the codes.
    pub fn family(&self) -> MarkerFamily {
        self.family
    }

    /// The guaranteed minimum Hamming distance `d_min`.
    pub fn min_distance(&self) -> u32 {
        self.min_distance
    }

    /// Most bit errors a lookup corrects: for a dictionary built here, `(d_min - 1) / 2`,
    /// the largest distance below `d_min / 2`.
    ///
    /// A predefined dictionary corrects OpenCV's default instead: `maxCorrectionBits`
    /// times OpenCV's `errorCorrectionRate` 0.6, rounded down (and never more than
    /// `(d_min - 1) / 2`); [`Dictionary::with_correction`] changes it.
    pub fn max_correctable(&self) -> u32 {
        self.correction
    }

    /// Every code under every quarter turn: `[i][q]` is entry `i` turned `q` clockwise
    /// quarter turns (slots a non-square family does not allow hold the code itself).
    pub(crate) fn rotated_codes(&self) -> &[[u64; 4]] {
        &self.rotated
    }

    /// Number of codes.
    pub fn len(&self) -> usize {
        self.codes.len()
    }

    /// Whether the dictionary has no codes (never true for a constructed dictionary).
    pub fn is_empty(&self) -> bool {
        self.codes.is_empty()
    }

    /// The codes, in index order.
    pub fn codes(&self) -> &[u64] {
        &self.codes
    }

    /// The code at `index`, if any.
    pub fn code(&self, index: usize) -> Option<u64> {
        self.codes.get(index).copied()
    }

    /// The index of an exact code (marker orientation), if present.
    pub fn index_of(&self, code: u64) -> Option<usize> {
        self.codes.iter().position(|&c| c == code)
    }

    /// Looks a read code up, correcting up to [`Dictionary::max_correctable`] bit errors.
    #[inline]
    pub fn lookup(&self, read: u64) -> Option<Match> {
        self.lookup_within(read, self.max_correctable())
    }

    /// Looks a read code up, accepting at most `max_errors` bit errors; values above
    /// [`Dictionary::max_correctable`] are lowered to it, so a match is always the unique
    /// entry within `d_min / 2`.
    pub fn lookup_within(&self, read: u64, max_errors: u32) -> Option<Match> {
        let limit = max_errors.min(self.max_correctable());
        if let Some(m) = self.exact(read) {
            return Some(m);
        }
        if limit == 0 {
            return None;
        }
        let bits = self.family.bits();
        let flips: u64 = (1..=limit).map(|k| choose(bits, k)).sum();
        if flips <= self.table.len() as u64 {
            // Every set of 1..=limit flipped bits, fewest first (Gosper's hack); within the
            // correction radius the match is unique.
            for k in 1..=limit {
                let mut set = (1u64 << k) - 1;
                while bits == 64 || set < 1u64 << bits {
                    if let Some(m) = self.exact(read ^ set) {
                        return Some(Match { distance: k, ..m });
                    }
                    let c = set & set.wrapping_neg();
                    let r = set.wrapping_add(c);
                    if r == 0 {
                        break;
                    }
                    set = (((r ^ set) >> 2) / c) | r;
                }
            }
            return None;
        }
        let sym = self.family.symmetries();
        let mut best: Option<Match> = None;
        for (index, r) in self.rotated.iter().enumerate() {
            for &q in sym {
                let distance = hamming(read, r[q as usize]);
                if distance <= limit && best.is_none_or(|b| distance < b.distance) {
                    best = Some(Match {
                        index,
                        code: r[0],
                        distance,
                        rotation: q,
                    });
                }
            }
        }
        best
    }

    /// The smallest distance from `read` to any entry under any rotation (no limit), with
    /// that entry: useful to tell "no match" from "nearly a match".
    pub fn nearest(&self, read: u64) -> Match {
        let sym = self.family.symmetries();
        let mut best = Match {
            index: 0,
            code: self.codes[0],
            distance: u32::MAX,
            rotation: 0,
        };
        for (index, r) in self.rotated.iter().enumerate() {
            for &q in sym {
                let distance = hamming(read, r[q as usize]);
                if distance < best.distance {
                    best = Match {
                        index,
                        code: r[0],
                        distance,
                        rotation: q,
                    };
                }
            }
        }
        best
    }

    /// The text form checked in under `data/`: `#` comments, `family RxC`,
    /// `min_distance D`, then one decimal code per line in index order.
    pub fn to_text(&self) -> String {
        let f = self.family;
        let mut s = String::new();
        s.push_str(
            "# Fiducial marker dictionary. Generated by `cargo xtask dictionary`; do not edit.\n",
        );
        s.push_str("# Code bit k = row * cols + col (row 0 top, col 0 left), black = 1.\n");
        s.push_str(&format!(
            "# {} codes; every pair and rotation (and each code against its own\n# rotations) differ in at least {} bits.\n",
            self.len(),
            self.min_distance
        ));
        s.push_str(&format!("family {}x{}\n", f.rows(), f.cols()));
        s.push_str(&format!("min_distance {}\n", self.min_distance));
        for (i, c) in self.codes.iter().enumerate() {
            s.push_str(&format!("{c}  # {i}\n"));
        }
        s
    }

    /// Parses [`Dictionary::to_text`] output and checks every distance constraint.
    pub fn from_text(text: &str) -> Result<Self, FiducialError> {
        let mut family = None;
        let mut min_distance = None;
        let mut codes = Vec::new();
        let err = |line: usize, reason: String| FiducialError::DictionaryParse { line, reason };
        for (i, raw) in text.lines().enumerate() {
            let line_no = i + 1;
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            if let Some(rest) = line.strip_prefix("family") {
                let (r, c) = rest
                    .trim()
                    .split_once('x')
                    .ok_or_else(|| err(line_no, format!("expected `family RxC`, got `{line}`")))?;
                let r: u32 = r
                    .trim()
                    .parse()
                    .map_err(|e| err(line_no, format!("rows: {e}")))?;
                let c: u32 = c
                    .trim()
                    .parse()
                    .map_err(|e| err(line_no, format!("cols: {e}")))?;
                family = Some(MarkerFamily::new(r, c)?);
            } else if let Some(rest) = line.strip_prefix("min_distance") {
                min_distance = Some(
                    rest.trim()
                        .parse::<u32>()
                        .map_err(|e| err(line_no, format!("min_distance: {e}")))?,
                );
            } else {
                if family.is_none() || min_distance.is_none() {
                    return Err(err(
                        line_no,
                        "codes must follow `family` and `min_distance`".to_string(),
                    ));
                }
                codes.push(
                    line.parse::<u64>()
                        .map_err(|e| err(line_no, format!("code `{line}`: {e}")))?,
                );
            }
        }
        let family = family.ok_or_else(|| err(0, "missing `family` line".to_string()))?;
        let min_distance =
            min_distance.ok_or_else(|| err(0, "missing `min_distance` line".to_string()))?;
        Self::new(family, min_distance, codes)
    }
}

/// A bijection of `[0, 2^bits)` (odd multiplications, xor-shifts and additions modulo
/// `2^bits`), so the greedy search visits every candidate once in a scrambled order.
fn permute(i: u64, bits: u32, seed: u64) -> u64 {
    let mask = if bits >= 64 {
        u64::MAX
    } else {
        (1u64 << bits) - 1
    };
    let shift = (bits / 2).max(1);
    let mut x = i & mask;
    for round in 0..3u64 {
        x = x.wrapping_mul(0x9E37_79B9_7F4A_7C15 | 1) & mask;
        x ^= x >> shift;
        x = x.wrapping_add(seed.wrapping_mul(0xD1B5_4A32_D192_ED03).wrapping_add(round)) & mask;
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn permute_is_a_bijection_on_small_domains() {
        for bits in [1u32, 4, 9, 12] {
            let n = 1u64 << bits;
            let mut seen = vec![false; n as usize];
            for i in 0..n {
                let p = permute(i, bits, 7);
                assert!(p < n);
                assert!(!seen[p as usize], "bits {bits}: {p} twice");
                seen[p as usize] = true;
            }
        }
    }

    #[test]
    fn new_rejects_close_codes_and_self_symmetric_codes() {
        let f = MarkerFamily::PAPER_4X5;
        // Two codes 1 bit apart.
        let a = 0b1010_0110_1001_0110_1010u64;
        assert!(matches!(
            Dictionary::new(f, 6, vec![a, a ^ 1]),
            Err(FiducialError::TooClose { .. })
        ));
        // A code equal to its own half turn: all cells black in the middle rows.
        let sym = 0b00000_11111_11111_00000u64;
        assert!(matches!(
            Dictionary::new(f, 6, vec![sym]),
            Err(FiducialError::TooClose {
                first: 0,
                second: 0,
                ..
            })
        ));
        assert!(matches!(
            Dictionary::new(f, 6, vec![]),
            Err(FiducialError::EmptyDictionary)
        ));
    }
}
