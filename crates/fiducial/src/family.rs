//! Marker families: the grid of data cells and the code's bit order (spec 3.1, 3.2).
//!
//! A marker of family `m x n` is `m` rows by `n` columns of data cells inside a black border
//! one cell wide, inside a white quiet zone. Cell `(row, col)` (row 0 at the top, col 0 at
//! the left, as the marker is printed) carries bit `k = row * n + col` of the code, black = 1:
//!
//! ```text
//! code = sum over data cells k of bit_k * 2^k
//! ```
//!
//! Rotations are clockwise quarter turns *as the marker is seen*. A square grid maps onto
//! itself under all four; a non-square one only under half turns.

use crate::error::FiducialError;

/// The grid of data cells of a square binary marker.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct MarkerFamily {
    rows: u8,
    cols: u8,
}

impl Default for MarkerFamily {
    /// The paper's family, [`MarkerFamily::PAPER_4X5`].
    fn default() -> Self {
        Self::PAPER_4X5
    }
}

impl MarkerFamily {
    /// The paper's family: 4 rows by 5 columns of data cells (20 bits).
    pub const PAPER_4X5: Self = Self { rows: 4, cols: 5 };

    /// Largest number of rows or columns (so a code fits in a `u64`).
    pub const MAX_SIDE: u32 = 8;

    /// A family of `rows x cols` data cells, each in `1..=8`.
    pub fn new(rows: u32, cols: u32) -> Result<Self, FiducialError> {
        if rows == 0 || cols == 0 || rows > Self::MAX_SIDE || cols > Self::MAX_SIDE {
            return Err(FiducialError::BadFamily { rows, cols });
        }
        Ok(Self {
            rows: rows as u8,
            cols: cols as u8,
        })
    }

    /// Rows of data cells (`m`).
    #[inline]
    pub fn rows(&self) -> u32 {
        u32::from(self.rows)
    }

    /// Columns of data cells (`n`).
    #[inline]
    pub fn cols(&self) -> u32 {
        u32::from(self.cols)
    }

    /// Number of data bits, `m * n`.
    #[inline]
    pub fn bits(&self) -> u32 {
        self.rows() * self.cols()
    }

    /// Mask of the valid code bits.
    #[inline]
    pub fn mask(&self) -> u64 {
        if self.bits() == 64 {
            u64::MAX
        } else {
            (1u64 << self.bits()) - 1
        }
    }

    /// Width of the marker in cells, border included (`n + 2`).
    #[inline]
    pub fn width_cells(&self) -> u32 {
        self.cols() + 2
    }

    /// Height of the marker in cells, border included (`m + 2`).
    #[inline]
    pub fn height_cells(&self) -> u32 {
        self.rows() + 2
    }

    /// Whether the grid is square (`m == n`), so that quarter turns map it onto itself.
    #[inline]
    pub fn is_square(&self) -> bool {
        self.rows == self.cols
    }

    /// The clockwise quarter turns under which the grid maps onto itself: `[0, 2]` for a
    /// non-square family, `[0, 1, 2, 3]` for a square one (spec 3.2).
    #[inline]
    pub fn symmetries(&self) -> &'static [u8] {
        if self.is_square() {
            &[0, 1, 2, 3]
        } else {
            &[0, 2]
        }
    }

    /// Checks that `code` has no bits beyond the family's data bits.
    pub fn check_code(&self, code: u64) -> Result<u64, FiducialError> {
        if code & !self.mask() != 0 {
            return Err(FiducialError::CodeOutOfRange {
                code,
                bits: self.bits(),
            });
        }
        Ok(code)
    }

    /// The bit of data cell `(row, col)` (black = `true`). Cells outside the grid read `false`.
    #[inline]
    pub fn bit(&self, code: u64, row: u32, col: u32) -> bool {
        row < self.rows() && col < self.cols() && (code >> (row * self.cols() + col)) & 1 == 1
    }

    /// The code of a grid given row by row (`bits[row * n + col]`, black = `true`).
    pub fn code_from_bits(&self, bits: &[bool]) -> Result<u64, FiducialError> {
        let expected = self.bits() as usize;
        if bits.len() != expected {
            return Err(FiducialError::BitCount {
                expected,
                got: bits.len(),
            });
        }
        Ok(bits
            .iter()
            .enumerate()
            .fold(0u64, |code, (k, &b)| code | (u64::from(b) << k)))
    }

    /// The grid of a code, row by row (`[row * n + col]`, black = `true`); the inverse of
    /// [`MarkerFamily::code_from_bits`]. Fills `out[..m * n]`; returns that slice.
    pub fn bits_of<'o>(&self, code: u64, out: &'o mut [bool; 64]) -> &'o [bool] {
        let n = self.bits() as usize;
        for (k, b) in out.iter_mut().take(n).enumerate() {
            *b = (code >> k) & 1 == 1;
        }
        &out[..n]
    }

    /// The code of the marker turned clockwise by `quarter_turns` quarter turns (as seen).
    ///
    /// A non-square family accepts only even numbers of quarter turns.
    pub fn rotate(&self, code: u64, quarter_turns: u8) -> Result<u64, FiducialError> {
        self.check_code(code)?;
        let q = quarter_turns % 4;
        if q % 2 == 1 && !self.is_square() {
            return Err(FiducialError::BadRotation {
                rows: self.rows(),
                cols: self.cols(),
                quarter_turns,
            });
        }
        Ok(self.rotate_unchecked(code, q))
    }

    /// [`MarkerFamily::rotate`] without the checks: `q` in `0..4`, odd only for a square
    /// family, and `code` within the mask.
    #[inline]
    pub(crate) fn rotate_unchecked(&self, code: u64, q: u8) -> u64 {
        let (m, n) = (self.rows(), self.cols());
        let mut out = 0u64;
        for r in 0..m {
            for c in 0..n {
                // The new cell (r, c) holds the old cell it came from.
                let (or, oc) = match q {
                    0 => (r, c),
                    // Clockwise: old (r, c) goes to new (c, n-1-r), so new (r, c) <- old
                    // (n-1-c, r) (square grid, m == n).
                    1 => (n - 1 - c, r),
                    2 => (m - 1 - r, n - 1 - c),
                    _ => (c, n - 1 - r),
                };
                if (code >> (or * n + oc)) & 1 == 1 {
                    out |= 1 << (r * n + c);
                }
            }
        }
        out
    }

    /// Black/white transitions between edge-adjacent data cells (horizontal and vertical).
    pub fn transitions(&self, code: u64) -> u32 {
        let (m, n) = (self.rows(), self.cols());
        let mut t = 0;
        for r in 0..m {
            for c in 0..n {
                let b = self.bit(code, r, c);
                if c + 1 < n && b != self.bit(code, r, c + 1) {
                    t += 1;
                }
                if r + 1 < m && b != self.bit(code, r + 1, c) {
                    t += 1;
                }
            }
        }
        t
    }

    /// Number of edge-adjacent pairs of data cells, `m (n-1) + (m-1) n`: the most
    /// transitions a code can have.
    pub fn adjacent_pairs(&self) -> u32 {
        let (m, n) = (self.rows(), self.cols());
        m * (n - 1) + (m - 1) * n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_families() {
        assert!(MarkerFamily::new(0, 3).is_err());
        assert!(MarkerFamily::new(9, 3).is_err());
        assert_eq!(MarkerFamily::new(8, 8).unwrap().mask(), u64::MAX);
    }

    #[test]
    fn square_quarter_turn_moves_top_left_to_top_right() {
        let f = MarkerFamily::new(3, 3).unwrap();
        let top_left = 1u64;
        let turned = f.rotate(top_left, 1).unwrap();
        assert!(f.bit(turned, 0, 2));
        assert_eq!(turned.count_ones(), 1);
    }

    #[test]
    fn non_square_refuses_quarter_turn() {
        let f = MarkerFamily::PAPER_4X5;
        assert!(matches!(
            f.rotate(1, 1),
            Err(FiducialError::BadRotation { .. })
        ));
        assert!(f.rotate(1 << 20, 0).is_err());
    }
}
