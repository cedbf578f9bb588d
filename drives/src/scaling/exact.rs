//! Exact arithmetic on dyadic rationals (an integer times a power of two, as every finite
//! `f64` is): what [`super::Scaling`] and [`super::ModuloCounts`] convert with.

/// `x = m · 2^e` with `m` odd (or 0); `x` must be finite.
pub(super) fn dyadic(x: f64) -> (i64, i32) {
    let raw = x.to_bits();
    let exp = ((raw >> 52) & 0x7ff) as i32;
    let frac = (raw & ((1u64 << 52) - 1)) as i64;
    let (m, e) = if exp == 0 {
        (frac, -1074)
    } else {
        (frac | (1 << 52), exp - 1075)
    };
    if m == 0 {
        return (0, 0);
    }
    let tz = m.trailing_zeros();
    let m = m >> tz;
    let e = e + tz as i32;
    if raw >> 63 == 1 {
        (-m, e)
    } else {
        (m, e)
    }
}

/// `x · 2^e`, exact unless the result overflows or underflows; steps of at most 2^±1000
/// keep each factor representable.
pub(super) fn scale2(x: f64, e: i32) -> f64 {
    let pow2 = |e: i32| f64::from_bits(((e + 1023) as u64) << 52);
    let (mut x, mut e) = (x, e);
    while e > 1000 && x.is_finite() && x != 0.0 {
        x *= pow2(1000);
        e -= 1000;
    }
    while e < -1000 && x.is_finite() && x != 0.0 {
        x *= pow2(-1000);
        e += 1000;
    }
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    x * pow2(e.clamp(-1022, 1023))
}

pub(super) fn gcd(mut a: u128, mut b: u128) -> u128 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a.max(1)
}

/// Number of significant bits.
pub(super) fn bits(x: u128) -> u32 {
    128 - x.leading_zeros()
}

/// The fractional part of an exact quotient.
#[derive(Clone, Copy, Debug)]
pub(super) enum Frac {
    /// `r / d` with `0 <= r < d`.
    Exact { r: u128, d: u128 },
    /// Known to lie in `[0, 1/4)` or `(3/4, 1)`, so rounding it in `f64` is safe.
    Approx(f64),
}

/// `x = q + frac`, `q = ⌊x⌋`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Split {
    pub(super) q: i128,
    pub(super) frac: Frac,
}

impl Split {
    /// `⌊x + ½⌋`, exactly.
    pub(super) fn round_half_up(&self) -> i128 {
        let up = match self.frac {
            Frac::Exact { r, d } => r >= d - r,
            Frac::Approx(f) => f >= 0.5,
        };
        self.q + i128::from(up)
    }

    /// The fractional part in `f64` (`[0, 1]` after rounding).
    pub(super) fn frac(&self) -> f64 {
        match self.frac {
            Frac::Exact { r, d } => r as f64 / d as f64,
            Frac::Approx(f) => f,
        }
    }
}

/// `n · 2^e / d` split into floor and fraction (`d > 0`); `None` if it is beyond ±2⁶⁴
/// (far outside the count range) or the operands are too wide (`|n| >= 2¹²⁰`,
/// `d >= 2⁸⁶`).
pub(super) fn scaled(n: i128, e: i32, d: u128) -> Option<Split> {
    if n == 0 {
        return Some(Split {
            q: 0,
            frac: Frac::Exact { r: 0, d: 1 },
        });
    }
    let nb = bits(n.unsigned_abs());
    if nb >= 120 || d == 0 || bits(d) >= 86 {
        return None;
    }
    let k = e.unsigned_abs();
    if e >= 0 {
        // |x| >= 2^(nb - 1 + e - bits(d)): beyond 2^64 means out of range.
        if (nb - 1 + k).saturating_sub(bits(d)) > 64 {
            return None;
        }
        let di = d as i128;
        let mut q = n.div_euclid(di);
        let mut r = n.rem_euclid(di);
        let mut left = k;
        while left > 0 {
            let step = left.min(40);
            // r < d < 2^86, so r << 40 < 2^126; q stays below 2^65 (checked below).
            q = q.checked_mul(1i128 << step)?;
            r <<= step;
            q = q.checked_add(r / di)?;
            r %= di;
            if q.unsigned_abs() > 1u128 << 65 {
                return None;
            }
            left -= step;
        }
        return Some(Split {
            q,
            frac: Frac::Exact { r: r as u128, d },
        });
    }
    if nb + 3 <= bits(d) + k {
        // |x| < 2^nb / 2^(bits(d) - 1 + k) <= 1/4: the quotient is 0 or −1, and the
        // fraction is far enough from ½ for `f64`.
        let x = scale2(n as f64 / d as f64, e);
        return Some(if n > 0 {
            Split {
                q: 0,
                frac: Frac::Approx(x),
            }
        } else {
            Split {
                q: -1,
                frac: Frac::Approx(1.0 + x),
            }
        });
    }
    // Here bits(d) + k < nb + 3 < 123, so d << k fits.
    let dd = d << k;
    let di = dd as i128;
    Some(Split {
        q: n.div_euclid(di),
        frac: Frac::Exact {
            r: n.rem_euclid(di) as u128,
            d: dd,
        },
    })
}

/// `⌊a · b / c⌋` and the remainder, for `|a| <= 2⁶³` and `0 < c < 2¹²⁷`, `b < 2¹²⁷`,
/// through a 192-bit product; `None` if the quotient does not fit `i128`.
pub(super) fn mul_div_floor(a: i128, b: u128, c: u128) -> Option<Split> {
    let mag = a.unsigned_abs();
    if mag > 1u128 << 63 || c == 0 || c >> 127 != 0 || b >> 127 != 0 {
        return None;
    }
    // product = hi · 2^128 + lo, from mag · (b1 · 2^64 + b0).
    let (b1, b0) = (b >> 64, b & u128::from(u64::MAX));
    let p0 = mag * b0;
    let p1 = mag * b1;
    let (lo, carry) = p0.overflowing_add(p1 << 64);
    let hi = (p1 >> 64) + u128::from(carry);
    let (q, r) = if hi == 0 {
        (lo / c, lo % c)
    } else {
        if hi >= c {
            return None;
        }
        // Long division, one bit at a time; r < c < 2^127 so 2r + 1 fits.
        let (mut q, mut r) = (0u128, hi);
        for i in (0..128).rev() {
            r = (r << 1) | ((lo >> i) & 1);
            q <<= 1;
            if r >= c {
                r -= c;
                q |= 1;
            }
        }
        (q, r)
    };
    let q = i128::try_from(q).ok()?;
    Some(if a >= 0 || r == 0 {
        Split {
            q: if a >= 0 { q } else { -q },
            frac: Frac::Exact { r, d: c },
        }
    } else {
        Split {
            q: -q - 1,
            frac: Frac::Exact { r: c - r, d: c },
        }
    })
}
