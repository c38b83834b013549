//! Reference tag corners of real photographs, as AprilTag 3 read them
//! (`fixtures/realdata/nasa/*.txt`, `shared/realdata/nasa/`): one tag per line,
//! `id, (x y), (x y), (x y), (x y)`, corners with pixel centres at half-integers. Read by the
//! detector's real-photo test and by `cargo xtask photos` / `compare`.

use nalgebra::Point2;

/// A reference tag: its id and its four corners in our convention (integer pixel centres).
pub type RefTag = (usize, [[f64; 2]; 4]);

/// The tags of a reference file's text. Blank lines are skipped; a line that is not
/// `id, (x y) x4` is an error naming its number and text.
///
/// # Errors
/// The first malformed line, as `line N: not ...: TEXT`.
pub fn parse(text: &str) -> Result<Vec<RefTag>, String> {
    let mut out = Vec::new();
    for (n, line) in text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
    {
        let bad = || format!("line {}: not `id, (x y) x4`: {line}", n + 1);
        let (id, rest) = line.split_once(',').ok_or_else(bad)?;
        let id: usize = id.trim().parse().map_err(|_| bad())?;
        let v: Vec<f64> = rest
            .split(|c: char| c == '(' || c == ')' || c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|_| bad())?;
        if v.len() != 8 {
            return Err(bad());
        }
        // AprilTag's pixel centres are at half-integers, ours at integers.
        out.push((
            id,
            core::array::from_fn(|i| [v[2 * i] - 0.5, v[2 * i + 1] - 0.5]),
        ));
    }
    Ok(out)
}

/// The largest distance from a corner of `want` to the nearest corner of `got` (any start:
/// AprilTag's corner order differs from ours).
pub fn corner_error(got: &[Point2<f64>; 4], want: &[[f64; 2]; 4]) -> f64 {
    want.iter()
        .map(|w| {
            got.iter()
                .map(|g| (g.x - w[0]).hypot(g.y - w[1]))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_parses_to_our_convention_and_a_bad_one_is_named() {
        let tags = parse("\n0, (10.5 20.5), (30.5 20.5), (30.5 40.5), (10.5 40.5)\n").unwrap();
        assert_eq!(
            tags,
            vec![(0, [[10.0, 20.0], [30.0, 20.0], [30.0, 40.0], [10.0, 40.0]])]
        );
        let got = [(30.0, 20.0), (30.0, 40.5), (10.0, 40.0), (10.0, 20.0)]
            .map(|(x, y)| Point2::new(x, y));
        assert!((corner_error(&got, &tags[0].1) - 0.5).abs() < 1e-12);
        let err = parse("0, (1 2), (3 4)\n").unwrap_err();
        assert!(err.starts_with("line 1:"), "{err}");
    }
}
