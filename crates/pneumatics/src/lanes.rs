//! Numbers the chamber equations are written in: one `f64`, or a [`Pack`] of them, one per plant, so
//! that the same expressions step one plant or several at once with packed arithmetic
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
