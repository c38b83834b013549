//! The marker family's bit order, rotations, and the dictionary's guarantees.

use fiducial::{Dictionary, FiducialError, GenerateParams, MarkerFamily, hamming};
use proptest::prelude::*;

/// The paper's Fig. 4 pattern, row 0 at the top, black = 1.
const FIG4: [&str; 4] = ["10010", "10101", "11100", "00101"];

fn grid(rows: &[&str]) -> Vec<bool> {
    rows.iter()
        .flat_map(|r| r.chars().map(|c| c == '1'))
        .collect()
}

#[test]
fn paper_fig4_code_round_trips() {
    let f = MarkerFamily::PAPER_4X5;
    let bits = grid(&FIG4);
    assert_eq!(f.code_from_bits(&bits).unwrap(), 663_209);
    let mut out = [false; 64];
    assert_eq!(f.bits_of(663_209, &mut out), &bits[..]);
    // Bit k = row * n + col: cell (1, 2) is bit 7.
    assert!(f.bit(663_209, 1, 2));
    assert!(!f.bit(663_209, 1, 1));
    assert!(matches!(
        f.code_from_bits(&bits[..19]),
        Err(FiducialError::BitCount {
            expected: 20,
            got: 19
        })
    ));
}

#[test]
fn half_turn_reverses_the_grid() {
    let f = MarkerFamily::PAPER_4X5;
    let turned = f.rotate(663_209, 2).unwrap();
    let expected: Vec<String> = FIG4
        .iter()
        .rev()
        .map(|r| r.chars().rev().collect())
        .collect();
    let expected: Vec<&str> = expected.iter().map(String::as_str).collect();
    assert_eq!(turned, f.code_from_bits(&grid(&expected)).unwrap());
}

#[test]
fn checked_in_dictionary_is_reproduced_by_the_generator() {
    let generated = Dictionary::generate(&GenerateParams::paper()).unwrap();
    assert_eq!(
        generated.to_text(),
        include_str!("../data/dict-4x5-d6.txt"),
        "data/dict-4x5-d6.txt is stale: run `cargo xtask dictionary`"
    );
    assert_eq!(&generated, Dictionary::paper());
}

#[test]
fn paper_dictionary_meets_its_constraints() {
    let d = Dictionary::paper();
    let f = d.family();
    assert_eq!(f, MarkerFamily::PAPER_4X5);
    assert_eq!(d.min_distance(), 6);
    assert_eq!(d.max_correctable(), 2);
    assert!(d.len() >= 40, "only {} codes", d.len());
    let p = GenerateParams::paper();
    for (i, &a) in d.codes().iter().enumerate() {
        assert!((p.min_black..=p.max_black).contains(&a.count_ones()));
        assert!(f.transitions(a) >= p.min_transitions);
        assert!(
            hamming(a, f.rotate(a, 2).unwrap()) >= 6,
            "code {i} vs its half turn"
        );
        for &b in &d.codes()[i + 1..] {
            for q in [0, 2] {
                assert!(hamming(a, f.rotate(b, q).unwrap()) >= 6);
            }
        }
    }
    // Re-validation from text catches a tampered file.
    let mut text = d.to_text();
    text.push_str(&format!("{}\n", d.codes()[0] ^ 0b11));
    assert!(matches!(
        Dictionary::from_text(&text),
        Err(FiducialError::TooClose { .. })
    ));
}

#[test]
fn from_text_reports_bad_lines() {
    assert!(matches!(
        Dictionary::from_text("family 4x5\nmin_distance 6\nabc\n"),
        Err(FiducialError::DictionaryParse { line: 3, .. })
    ));
    assert!(matches!(
        Dictionary::from_text("min_distance 6\n"),
        Err(FiducialError::DictionaryParse { .. })
    ));
    assert!(matches!(
        Dictionary::from_text("family 4x5\nmin_distance 6\n1048576\n"),
        Err(FiducialError::CodeOutOfRange { .. })
    ));
}

#[test]
fn square_dictionary_separates_quarter_turns() {
    let f = MarkerFamily::new(5, 5).unwrap();
    let mut p = GenerateParams::for_family(f, 7);
    p.max_codes = 30;
    let d = Dictionary::generate(&p).unwrap();
    assert!(d.len() >= 10, "{}", d.len());
    for (i, &c) in d.codes().iter().enumerate() {
        for q in 0..4 {
            let m = d.lookup(f.rotate(c, q).unwrap()).unwrap();
            assert_eq!((m.index, m.rotation, m.distance), (i, q, 0));
        }
    }
}

fn flip(code: u64, bits: &[usize]) -> u64 {
    bits.iter().fold(code, |c, &k| c ^ (1 << k))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Rotating four quarter turns (square) or two half turns is the identity.
    #[test]
    fn rotations_compose(code in 0u64..(1 << 25), q in 0u8..4) {
        let f = MarkerFamily::new(5, 5).unwrap();
        let once = f.rotate(code, q).unwrap();
        prop_assert_eq!(f.rotate(once, (4 - q) % 4).unwrap(), code);
        prop_assert_eq!(once.count_ones(), code.count_ones());
    }

    /// A lookup never returns an entry at distance >= d_min / 2, whatever is read: reads
    /// anywhere, and reads 0..=6 bits from an entry (where near misses live).
    #[test]
    fn lookup_never_accepts_a_far_code(
        random in 0u64..(1 << 20),
        near in any::<bool>(),
        index in 0usize..1000,
        flips in proptest::sample::subsequence((0..20).collect::<Vec<usize>>(), 0..=6),
        limit in 0u32..5,
    ) {
        let d = Dictionary::paper();
        let read = if near { flip(d.codes()[index % d.len()], &flips) } else { random };
        let found = d.lookup_within(read, limit);
        let nearest = d.nearest(read);
        if let Some(m) = found {
            prop_assert!(m.distance * 2 < d.min_distance());
            prop_assert!(m.distance <= limit);
            let f = d.family();
            prop_assert_eq!(hamming(read, f.rotate(m.code, m.rotation).unwrap()), m.distance);
            prop_assert_eq!(d.codes()[m.index], m.code);
            prop_assert_eq!(m, nearest);
        } else {
            prop_assert!(nearest.distance > limit.min(d.max_correctable()));
        }
    }

    /// Up to two flips are corrected with the right orientation; three never give a wrong
    /// entry (and, since the entry is at distance 3, are rejected).
    #[test]
    fn flips_are_corrected_or_rejected(
        index in 0usize..1000,
        q in prop_oneof![Just(0u8), Just(2u8)],
        flips in proptest::sample::subsequence((0..20).collect::<Vec<usize>>(), 0..=3),
    ) {
        let d = Dictionary::paper();
        let index = index % d.len();
        let f = d.family();
        let read = flip(f.rotate(d.codes()[index], q).unwrap(), &flips);
        match d.lookup(read) {
            Some(m) => {
                prop_assert!(flips.len() <= 2);
                prop_assert_eq!((m.index, m.rotation, m.distance as usize), (index, q, flips.len()));
            }
            None => prop_assert_eq!(flips.len(), 3),
        }
    }
}
