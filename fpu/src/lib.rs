//! Two instructions of the board for ferroslam's core, in one place: the f32 square root on the
//! FPU, and a dual 16-bit multiply-accumulate ([`smlad`]).
//!
//! `ferroslam-core` forbids `unsafe` code and computes its transcendental functions with the
//! pure-Rust `libm` so the host and the Cortex-M give the same bits. A square root is the one
//! exception worth a crate: IEEE 754 requires `sqrt` to be correctly rounded, the Cortex-M4F's
//! FPU has an instruction for it (`VSQRT.F32`, 14 cycles), and `libm::sqrtf` computes the very
//! same correctly rounded result in software, some hundred instructions a call. On the board the
//! core's keypoint and matching code calls it tens of thousands of times on a costly frame
//! (`cargo xtask profile-firmware` put `libm::sqrtf` at 0.48 M instructions on the costliest
//! frame of the 1000-frame budget replay; 0.05 M with this crate).
//!
//! The `unsafe` blocks of the core's dependency tree that are ours live here: five instructions
//! of inline assembly for the root and one for [`smlad`], on `all(target_arch = "arm",
//! target_abi = "eabihf")` only (the FPU registers are the hard-float ABI's; every such Cortex-M
//! has the DSP extension). Elsewhere [`sqrtf`] is `libm::sqrtf`. Both are
//! correctly rounded for every input (IEEE 754 `squareRoot`, round to nearest even), so the
//! results are bit-identical; the host tests check libm against an exact integer reference, and
//! the firmware's budget replay (`cargo xtask budgets`) checks the board's output bits against
//! the host's frame by frame.
//!
//! Why inline assembly and not `core::intrinsics` or `f32::sqrt`: `f32::sqrt` is in `std`, not
//! `core`, on Rust 1.95, and the `sqrtf32` intrinsic is unstable. The `sreg` register class
//! would save the two moves, but it needs the `vfp2` target feature, which is unstable too, so
//! the value goes through a core register and `s0` is saved and restored around it.
//!
//! [`smlad`], the Cortex-M4's dual 16-bit multiply-accumulate, does two products and their sum
//! in one instruction in the core's integer template search, the matching's innermost loop
//! (docs/decisions.md, "Batched search products"). It is exact integer arithmetic, so its plain
//! Rust form elsewhere gives the same bits. Assembly again, as `core::arch::arm::__smlad` is
//! unstable on Rust 1.95.
#![no_std]
#![deny(missing_docs)]

/// The square root of `x`, correctly rounded (round to nearest, ties to even).
///
/// `sqrtf(-0.0)` is `-0.0`, a negative `x` or a NaN gives a NaN, `sqrtf(inf)` is `inf`: IEEE 754,
/// on every target.
///
/// ```
/// assert_eq!(ferroslam_fpu::sqrtf(2.25), 1.5);
/// assert!(ferroslam_fpu::sqrtf(-1.0).is_nan());
/// ```
#[inline]
#[must_use]
pub fn sqrtf(x: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        let r: u32;
        // SAFETY: the assembly reads and writes only the two named core registers and `s0`,
        // which it saves on the stack and restores (it pushes and pops 4 bytes, keeping the
        // stack balanced). `VSQRT.F32` has no side effect other than the FPSCR's cumulative
        // exception flags (inexact, invalid), which is why `preserves_flags` is not claimed.
        unsafe {
            core::arch::asm!(
                "vpush {{s0}}",
                "vmov s0, {x}",
                "vsqrt.f32 s0, s0",
                "vmov {r}, s0",
                "vpop {{s0}}",
                x = in(reg) x.to_bits(),
                r = lateout(reg) r,
                options(pure, nomem),
            );
        }
        f32::from_bits(r)
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}

/// `acc + lo(a) * lo(b) + hi(a) * hi(b)`, wrapping modulo 2^32, where `lo` and `hi` are the
/// signed 16-bit halves of a word (bits 0-15 and 16-31): two multiply-accumulates.
///
/// On hard-float ARM it is one `SMLAD` (every Cortex-M4F and M7F has the DSP extension); the
/// same sum in plain integers elsewhere. Both wrap the same way, so the results are the same
/// bits; `SMLAD` also sets the Q flag on a wrap, which nothing reads.
///
/// ```
/// let pair = |lo: i16, hi: i16| u32::from(lo as u16) | (u32::from(hi as u16) << 16);
/// assert_eq!(ferroslam_fpu::smlad(pair(3, -4), pair(5, 6), 100), 100 + 15 - 24);
/// ```
#[inline(always)]
#[must_use]
pub fn smlad(a: u32, b: u32, acc: i32) -> i32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        let r: i32;
        // SAFETY: one instruction on the three named input registers and the output register;
        // it reads and writes no memory and no stack. It may set the Q flag (sticky saturation),
        // which is why `preserves_flags` is not claimed.
        unsafe {
            core::arch::asm!(
                "smlad {r}, {a}, {b}, {acc}",
                a = in(reg) a,
                b = in(reg) b,
                acc = in(reg) acc,
                r = lateout(reg) r,
                options(pure, nomem, nostack),
            );
        }
        r
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        let lo = |w: u32| i32::from(w as u16 as i16);
        let hi = |w: u32| i32::from((w >> 16) as u16 as i16);
        acc.wrapping_add(lo(a) * lo(b)).wrapping_add(hi(a) * hi(b))
    }
}

#[cfg(test)]
mod tests {
    use super::{smlad, sqrtf};

    #[test]
    fn smlad_adds_both_halves_products_and_wraps() {
        let pair = |lo: i16, hi: i16| u32::from(lo as u16) | (u32::from(hi as u16) << 16);
        assert_eq!(smlad(pair(255, 0), pair(-128, 127), 7), 7 - 255 * 128);
        assert_eq!(smlad(pair(-1, -1), pair(-1, -1), 0), 2);
        assert_eq!(smlad(pair(0, 255), pair(0, 127), -1), 255 * 127 - 1);
        // (-2^15)^2 twice is 2^31: it wraps, as SMLAD does.
        assert_eq!(smlad(pair(i16::MIN, i16::MIN), pair(i16::MIN, i16::MIN), 0), i32::MIN);
        assert_eq!(smlad(0, 0, i32::MAX), i32::MAX);
    }

    /// The correctly rounded square root of a positive finite `x`, from integers only: the
    /// reference the FPU's `VSQRT.F32` and libm both meet.
    fn reference(x: f32) -> f32 {
        // x = m * 2^e with m an integer; m is scaled by 2^100 or 2^101 so that its integer root
        // has about 62 bits to round to 24 from.
        let bits = x.to_bits();
        let exp = ((bits >> 23) & 0xff) as i32;
        let (mant, e) = if exp == 0 {
            (u128::from(bits & 0x7f_ffff), -149)
        } else {
            (u128::from((bits & 0x7f_ffff) | 0x80_0000), exp - 150)
        };
        // Make the exponent even and the integer large: m' = m * 2^(2k), e' = e - 2k.
        let shift = 100 + (e & 1);
        let m = mant << shift;
        let e2 = e - shift; // even
        let r = isqrt(m); // floor(sqrt(m))
        let exact = r * r == m;
        // sqrt(x) = sqrt(m) * 2^(e2/2); r has about 62 bits; round to 24 significant bits.
        let bits_r = 128 - r.leading_zeros() as i32;
        let drop = bits_r - 24;
        let mut q = r >> drop;
        let rem = r & ((1u128 << drop) - 1);
        let half = 1u128 << (drop - 1);
        // sqrt(m) is never exactly half-way between two 24-bit values unless r is exact.
        if rem > half || (rem == half && (!exact || q & 1 == 1)) {
            q += 1;
        }
        let value = q as f64 * 2f64.powi(drop + e2 / 2);
        value as f32
    }

    fn isqrt(n: u128) -> u128 {
        if n == 0 {
            return 0;
        }
        let mut x = 1u128 << (128 - n.leading_zeros()).div_ceil(2);
        loop {
            let y = (x + n / x) / 2;
            if y >= x {
                return x;
            }
            x = y;
        }
    }

    #[test]
    fn correctly_rounded_over_many_values() {
        let mut checked = 0;
        // Every 2^16-th bit pattern of the positive finite floats, subnormals included.
        for bits in (1u32..0x7f80_0000).step_by(1 << 16) {
            let x = f32::from_bits(bits);
            assert_eq!(sqrtf(x).to_bits(), reference(x).to_bits(), "sqrt of {x:e}");
            checked += 1;
        }
        // Dense around 1 and the sizes the core sees (squared pixel and metre distances).
        for bits in (0x3f00_0000u32..0x4100_0000).step_by(1 << 10) {
            let x = f32::from_bits(bits);
            assert_eq!(sqrtf(x).to_bits(), reference(x).to_bits(), "sqrt of {x:e}");
            checked += 1;
        }
        assert!(checked > 30_000);
    }

    #[test]
    fn ieee_special_values() {
        assert_eq!(sqrtf(0.0).to_bits(), 0.0f32.to_bits());
        assert_eq!(sqrtf(-0.0).to_bits(), (-0.0f32).to_bits());
        assert_eq!(sqrtf(f32::INFINITY), f32::INFINITY);
        assert!(sqrtf(-1.0).is_nan());
        assert!(sqrtf(f32::NEG_INFINITY).is_nan());
        assert!(sqrtf(f32::NAN).is_nan());
        assert_eq!(sqrtf(4.0), 2.0);
        assert_eq!(sqrtf(f32::MAX).to_bits(), reference(f32::MAX).to_bits());
        assert_eq!(sqrtf(f32::from_bits(1)).to_bits(), reference(f32::from_bits(1)).to_bits());
    }
}
