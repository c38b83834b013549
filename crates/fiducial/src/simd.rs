//! Run-time CPU feature checks for the few loops that are compiled twice, for the baseline
//! instruction set and for AVX2 (`#[target_feature]`), and chosen per call.
//!
//! Only the binarization's extremes and cut ([`crate::threshold`]) are compiled so: 16-bit
//! loops over whole rows, which take 16 pixels at a time with AVX2 instead of 8 (on the
//! demo frame at 640x480, binarization took 62 us instead of 82). The labeller's row scan
//! and the re-cut's tiles and cut were tried and gained nothing measurable, so they are
//! not. The code is the same in both compilations (the same source, inlined into each) and
//! integer-only, so both give the same bits; a test compares them. The crate's only
//! `unsafe` is the call of such a function once the check has passed ([`with_avx2`]).

/// Whether the CPU has AVX2 (std caches the answer after the first call).
#[cfg(target_arch = "x86_64")]
#[inline]
pub(crate) fn avx2() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
}

/// Defines `fn $name(args) -> ret` that runs `$body(args)` (an `#[inline(always)]`
/// function) compiled for AVX2 when the CPU has it (x86-64), and for the baseline otherwise.
macro_rules! with_avx2 {
    ($(#[$m:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? = $body:path;) => {
        $(#[$m])*
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            if $crate::simd::avx2() {
                #[target_feature(enable = "avx2")]
                fn avx2($($arg: $ty),*) $(-> $ret)? {
                    $body($($arg),*)
                }
                // SAFETY: the CPU has AVX2 (checked at run time just above), which is all
                // that calling a function compiled with `target_feature(enable = "avx2")`
                // requires.
                #[allow(unsafe_code)]
                return unsafe { avx2($($arg),*) };
            }
            $body($($arg),*)
        }
    };
}

pub(crate) use with_avx2;
