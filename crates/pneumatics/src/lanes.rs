//! Numbers the chamber equations and the smooth friction are written in: one `f64`, or a [`Pack`] of them,
//! one per plant, so that the same expressions step one plant or several at once with packed arithmetic
//! ([`crate::advance_together`]). Every operation is the IEEE one applied lane by lane, so a plant in a
//! pack follows, bit for bit, the path it follows alone.

// Lane loops index their arrays by lane: each is one packed instruction.
#![allow(clippy::needless_range_loop)]

use core::ops::{Add, Div, Mul, Neg, Sub};

/// A number, or several side by side; comparisons give a mask that [`Real::select`] reads.
pub(crate) trait Real:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    type Mask: Copy;
    fn splat(v: f64) -> Self;
    fn sqrt(self) -> Self;
    /// `f64::max` per lane.
    fn max(self, o: Self) -> Self;
    /// `f64::clamp` per lane.
    fn clamp(self, lo: f64, hi: f64) -> Self;
    /// `f64::abs` per lane.
    fn abs(self) -> Self;
    /// `f64::copysign` per lane.
    fn copysign(self, sign: Self) -> Self;
    /// `f64::signum` per lane.
    fn signum(self) -> Self;
    /// `2^k` from `self = k + SHIFTER` with an integral `k` in -1022..=1023: `k` is then the low bits of
    /// `self`'s mantissa ([`tanh`]'s range reduction).
    fn pow2_shifted(self) -> Self;
    fn le(self, o: Self) -> Self::Mask;
    fn lt(self, o: Self) -> Self::Mask;
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    fn or(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// `a` where `m` holds, else `b`, per lane.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
    /// Whether this is one number ([`pick!`] branches on [`Real::taken`]) or a pack (it blends).
    const ONE: bool;
    /// The mask of one number as a bool (a pack's is never asked).
    fn taken(m: Self::Mask) -> bool;
}

/// `pick!(R; m => a, b)`: `a` where the mask `m` holds, else `b` (arrays of `R`), per lane. One number
/// evaluates only the branch it takes (the work of a shut path or of another regime is not done); a pack
/// evaluates both and blends them. A macro, not a function taking closures: the branches are then
/// compiled in place, with the caller's instruction set (a closure is a function of its own).
macro_rules! pick {
    ($r:ty; $m:expr => $a:expr, $b:expr) => {{
        let m = $m;
        if <$r as $crate::lanes::Real>::ONE {
            if <$r as $crate::lanes::Real>::taken(m) {
                $a
            } else {
                $b
            }
        } else {
            let (a, b) = ($a, $b);
            let mut r = a;
            for j in 0..r.len() {
                r[j] = <$r as $crate::lanes::Real>::select(m, a[j], b[j]);
            }
            r
        }
    }};
}
pub(crate) use pick;

impl Real for f64 {
    type Mask = bool;
    #[inline(always)]
    fn splat(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        f64::max(self, o)
    }
    #[inline(always)]
    fn clamp(self, lo: f64, hi: f64) -> Self {
        f64::clamp(self, lo, hi)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f64::abs(self)
    }
    #[inline(always)]
    fn copysign(self, sign: Self) -> Self {
        f64::copysign(self, sign)
    }
    #[inline(always)]
    fn signum(self) -> Self {
        f64::signum(self)
    }
    #[inline(always)]
    fn pow2_shifted(self) -> Self {
        pow2_shifted(self)
    }
    #[inline(always)]
    fn le(self, o: Self) -> bool {
        self <= o
    }
    #[inline(always)]
    fn lt(self, o: Self) -> bool {
        self < o
    }
    #[inline(always)]
    fn and(a: bool, b: bool) -> bool {
        a && b
    }
    #[inline(always)]
    fn or(a: bool, b: bool) -> bool {
        a || b
    }

    #[inline(always)]
    fn select(m: bool, a: Self, b: Self) -> Self {
        if m { a } else { b }
    }
    const ONE: bool = true;
    #[inline(always)]
    fn taken(m: bool) -> bool {
        m
    }
}

/// `N` numbers, one per plant, operated on lane by lane (loops the compiler turns into packed
/// instructions).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(align(32))]
pub(crate) struct Pack<const N: usize>(pub(crate) [f64; N]);

// Plain loops over the lanes (no closures: they would be compiled apart from the caller).
macro_rules! pack_op {
    ($tr:ident, $f:ident, $op:tt) => {
        impl<const N: usize> $tr for Pack<N> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                let mut r = self.0;
                for i in 0..N {
                    r[i] = self.0[i] $op o.0[i];
                }
                Self(r)
            }
        }
    };
}
pack_op!(Add, add, +);
pack_op!(Sub, sub, -);
pack_op!(Mul, mul, *);
pack_op!(Div, div, /);

impl<const N: usize> Neg for Pack<N> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        let mut r = self.0;
        for a in &mut r {
            *a = -*a;
        }
        Self(r)
    }
}

impl<const N: usize> Real for Pack<N> {
    /// Per lane: all bits set where the comparison holds (the form a blend reads).
    type Mask = [u64; N];
    #[inline(always)]
    fn splat(v: f64) -> Self {
        Self([v; N])
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let mut r = self.0;
        for a in &mut r {
            *a = a.sqrt();
        }
        Self(r)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        let mut r = self.0;
        for i in 0..N {
            r[i] = self.0[i].max(o.0[i]);
        }
        Self(r)
    }
    #[inline(always)]
    fn clamp(self, lo: f64, hi: f64) -> Self {
        let mut r = self.0;
        for a in &mut r {
            *a = a.clamp(lo, hi);
        }
        Self(r)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        let mut r = self.0;
        for a in &mut r {
            *a = a.abs();
        }
        Self(r)
    }
    #[inline(always)]
    fn copysign(self, sign: Self) -> Self {
        let mut r = self.0;
        for i in 0..N {
            r[i] = r[i].copysign(sign.0[i]);
        }
        Self(r)
    }
    #[inline(always)]
    fn signum(self) -> Self {
        let mut r = self.0;
        for a in &mut r {
            *a = a.signum();
        }
        Self(r)
    }
    #[inline(always)]
    fn pow2_shifted(self) -> Self {
        let mut r = self.0;
        for a in &mut r {
            *a = pow2_shifted(*a);
        }
        Self(r)
    }
    #[inline(always)]
    fn le(self, o: Self) -> Self::Mask {
        let mut m = [0; N];
        for i in 0..N {
            m[i] = if self.0[i] <= o.0[i] { u64::MAX } else { 0 };
        }
        m
    }
    #[inline(always)]
    fn lt(self, o: Self) -> Self::Mask {
        let mut m = [0; N];
        for i in 0..N {
            m[i] = if self.0[i] < o.0[i] { u64::MAX } else { 0 };
        }
        m
    }
    #[inline(always)]
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        let mut m = [0; N];
        for i in 0..N {
            m[i] = a[i] & b[i];
        }
        m
    }
    #[inline(always)]
    fn or(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        let mut m = [0; N];
        for i in 0..N {
            m[i] = a[i] | b[i];
        }
        m
    }

    #[inline(always)]
    fn select(m: Self::Mask, a: Self, b: Self) -> Self {
        // A bitwise blend: the selected lane's bits, exactly.
        let mut r = [0.0; N];
        for i in 0..N {
            r[i] = f64::from_bits((a.0[i].to_bits() & m[i]) | (b.0[i].to_bits() & !m[i]));
        }
        Self(r)
    }
    const ONE: bool = false;
    #[inline(always)]
    fn taken(_: Self::Mask) -> bool {
        unreachable!("a pack blends")
    }
}

/// `1.5 * 2^52`: adding it to a number of magnitude below 2^51 rounds that number to the nearest integer
/// (ties to even), which is then the low bits of the sum's mantissa.
const SHIFTER: f64 = 6_755_399_441_055_744.0;

/// `2^k` for `s = k + SHIFTER` (integer arithmetic on the bits, which packs: no conversion to an integer).
#[inline(always)]
fn pow2_shifted(s: f64) -> f64 {
    let k = s.to_bits().wrapping_sub(SHIFTER.to_bits());
    f64::from_bits(k.wrapping_add(1023) << 52)
}

/// `tanh(y)` with IEEE arithmetic only, so that one plant and a pack of them give the same bits (libm's
/// `tanh` is one call per lane). `tanh|y| = -E / (E + 2)` with `E = expm1(-2|y|)` in (-1, 0]: neither the
/// sum nor the quotient cancels; the sign is put back last, so the function is odd to the bit. Within 3 ulp
/// of libm's over |y| < 20 (`tests` checks 4); callers take the sign beyond, where tanh rounds to +-1.
#[inline(always)]
pub(crate) fn tanh<R: Real>(y: R) -> R {
    let e = expm1_nonpositive(R::splat(-2.0) * y.abs());
    (-e / (e + R::splat(2.0))).copysign(y)
}

/// `exp(z) - 1` for `-1000 < z <= 0`: `z = k ln 2 + r` with an integral `k` and `|r| <= ln 2 / 2`
/// (Cody and Waite's split of ln 2, whose high part times `k` is exact), `expm1(r)` from its Taylor series to
/// `r^13 / 13!` (the next term is below 0.1 ulp of the sum; Estrin's order), then `2^k expm1(r) + (2^k - 1)`:
/// both products exact, one rounding in the sum.
#[inline(always)]
fn expm1_nonpositive<R: Real>(z: R) -> R {
    // ln 2 = LN2_HI + LN2_LO, LN2_HI with 32 trailing zero bits (6.9314718036912382e-1, 1.9082149292705877e-10).
    const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
    const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
    let shifted = z * R::splat(core::f64::consts::LOG2_E) + R::splat(SHIFTER);
    let k = shifted - R::splat(SHIFTER);
    let r = (z - k * R::splat(LN2_HI)) - k * R::splat(LN2_LO);
    // expm1(r) = r + r^2 P(r), P(r) = sum of r^i / (i + 2)! for i = 0..=11, in Estrin's scheme: pairs, then
    // pairs of pairs with r^2, r^4, r^8 (a chain of 4 product-sums where Horner's has 11: the friction's
    // tanh is on every RK4 stage's critical path).
    // 1/n! for n = 2..=13.
    const C: [f64; 12] = [
        0.5,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
        1.0 / 5_040.0,
        1.0 / 40_320.0,
        1.0 / 362_880.0,
        1.0 / 3_628_800.0,
        1.0 / 39_916_800.0,
        1.0 / 479_001_600.0,
        1.0 / 6_227_020_800.0,
    ];
    let c = C.map(R::splat);
    let r2 = r * r;
    let r4 = r2 * r2;
    let r8 = r4 * r4;
    let s0 = (c[0] + c[1] * r) + (c[2] + c[3] * r) * r2;
    let s1 = (c[4] + c[5] * r) + (c[6] + c[7] * r) * r2;
    let s2 = (c[8] + c[9] * r) + (c[10] + c[11] * r) * r2;
    let s = (s0 + s1 * r4) + s2 * r8;
    let p = r + r2 * s;
    let two_k = shifted.pow2_shifted();
    two_k * p + (two_k - R::splat(1.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units in the last place between two finite numbers of one sign.
    fn ulps(a: f64, b: f64) -> u64 {
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs()
    }

    /// Our tanh against libm's (an independent implementation) over |y| < 20, densely near 0 where the
    /// series and the reduction meet, and at the edges of the reduction's intervals (k ln 2 / 2).
    #[test]
    fn tanh_is_libms_to_four_ulp() {
        let mut worst = (0, 0.0);
        let mut check = |y: f64| {
            let (ours, libm) = (tanh(y), y.tanh());
            let d = ulps(ours, libm);
            assert!(d <= 4, "tanh({y:e}) = {ours:e}, libm {libm:e}: {d} ulp");
            assert_eq!(tanh(-y).to_bits(), (-ours).to_bits(), "odd at {y:e}");
            if d > worst.0 {
                worst = (d, y);
            }
        };
        for i in 0..200_000 {
            check(20.0 * f64::from(i) / 200_000.0);
        }
        for e in -300..0 {
            check(10f64.powi(e) * 1.234_567);
        }
        for k in 1..58 {
            let edge = f64::from(k) * core::f64::consts::LN_2 / 4.0;
            for d in -50..=50 {
                check(edge + f64::from(d) * 1e-16 * edge);
            }
        }
        assert_eq!(tanh(0.0f64).to_bits(), 0.0f64.to_bits());
        assert_eq!(tanh(-0.0f64).to_bits(), (-0.0f64).to_bits());
        assert!(tanh(f64::NAN).is_nan());
        // A pack gives each lane's own bits.
        let ys = [0.0, -1e-9, 0.17, -0.35, 1.0, -3.3, 9.9, 19.9];
        let packed = tanh(Pack(ys));
        for (y, t) in ys.iter().zip(packed.0) {
            assert_eq!(tanh(*y).to_bits(), t.to_bits());
        }
        eprintln!("worst: {} ulp at {:e}", worst.0, worst.1);
    }
}
