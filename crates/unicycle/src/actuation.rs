//! How a robot executes its commands: a scale error per input and white noise.

use crate::error::{UnicycleError, check_finite};
use crate::robot::Inputs;

/// The errors between the inputs a robot is commanded and those its wheels execute:
/// `executed = scale * commanded + noise_std * n`, per input (`[v, w]`), with `n` standard
/// normal draws the caller supplies (this crate has no randomness). A real robot's wheels
/// slip and its motor controllers have gains that are not exactly one; an estimator must
/// not assume that what it commanded is what happened.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields, default))]
pub struct Actuation {
    /// Scale of each executed input against the commanded one, `[v, w]` (1: exact).
    pub scale: [f64; 2],
    /// Standard deviation of the white noise on each executed input: m/s for `v`, rad/s
    /// for `w` (0: none).
    pub noise_std: [f64; 2],
}

impl Actuation {
    /// Actuation without error: the commanded inputs are executed exactly.
    pub const PERFECT: Self = Self {
        scale: [1.0, 1.0],
        noise_std: [0.0, 0.0],
    };

    /// Whether every command is executed exactly.
    pub fn is_perfect(&self) -> bool {
        *self == Self::PERFECT
    }

    /// Checks the settings: finite, scales in `(0, 2]` (a robot that drives backwards or at
    /// more than twice its command is broken, not imprecise), deviations non-negative.
    ///
    /// # Errors
    /// [`UnicycleError::NonFinite`] or [`UnicycleError::InvalidActuation`], naming the
    /// setting.
    pub fn validate(&self) -> Result<(), UnicycleError> {
        check_finite("actuation scale", &self.scale)?;
        check_finite("actuation noise_std", &self.noise_std)?;
        for (name, s) in [("scale[0]", self.scale[0]), ("scale[1]", self.scale[1])] {
            if !(s > 0.0 && s <= 2.0) {
                return Err(UnicycleError::InvalidActuation { name, value: s });
            }
        }
        for (name, s) in [
            ("noise_std[0]", self.noise_std[0]),
            ("noise_std[1]", self.noise_std[1]),
        ] {
            if s < 0.0 {
                return Err(UnicycleError::InvalidActuation { name, value: s });
            }
        }
        Ok(())
    }

    /// The inputs executed for `commanded`, with `n` two standard normal draws (`[v, w]`).
    /// Exact (bit for bit) when the actuation is [perfect](Self::PERFECT).
    pub fn execute(&self, commanded: Inputs, n: [f64; 2]) -> Inputs {
        let one = |c: f64, scale: f64, std: f64, n: f64| {
            let scaled = if scale == 1.0 { c } else { scale * c };
            if std == 0.0 { scaled } else { scaled + std * n }
        };
        Inputs::new(
            one(commanded.v, self.scale[0], self.noise_std[0], n[0]),
            one(commanded.w, self.scale[1], self.noise_std[1], n[1]),
        )
    }
}

impl Default for Actuation {
    fn default() -> Self {
        Self::PERFECT
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn perfect_actuation_executes_the_command_exactly_whatever_the_draws() {
        let u = Inputs::new(0.8, -0.2);
        assert!(Actuation::PERFECT.is_perfect());
        assert_eq!(Actuation::PERFECT.execute(u, [3.0, -2.0]), u);
        assert_eq!(Actuation::default(), Actuation::PERFECT);
    }

    #[test]
    fn scale_and_noise_apply_per_input() {
        let a = Actuation {
            scale: [0.95, 1.0],
            noise_std: [0.03, 0.01],
        };
        let e = a.execute(Inputs::new(1.0, 0.5), [1.0, -2.0]);
        assert!((e.v - (0.95 + 0.03)).abs() < 1e-15, "{e:?}");
        assert!((e.w - (0.5 - 0.02)).abs() < 1e-15, "{e:?}");
    }

    #[test]
    fn bad_settings_are_errors_naming_the_setting() {
        let bad = |scale: [f64; 2], noise_std: [f64; 2]| Actuation { scale, noise_std }.validate();
        assert!(bad([1.0, 1.0], [0.0, 0.0]).is_ok());
        assert!(matches!(
            bad([0.0, 1.0], [0.0, 0.0]),
            Err(UnicycleError::InvalidActuation {
                name: "scale[0]",
                ..
            })
        ));
        assert!(matches!(
            bad([1.0, 2.5], [0.0, 0.0]),
            Err(UnicycleError::InvalidActuation {
                name: "scale[1]",
                ..
            })
        ));
        assert!(matches!(
            bad([1.0, 1.0], [0.0, -0.1]),
            Err(UnicycleError::InvalidActuation {
                name: "noise_std[1]",
                ..
            })
        ));
        assert!(matches!(
            bad([f64::NAN, 1.0], [0.0, 0.0]),
            Err(UnicycleError::NonFinite { .. })
        ));
    }
}
