//! Peak stack measurement by painting: [`paint`] fills the free RAM between the end of the statics
//! and the current stack pointer with a pattern, [`peak_bytes`] finds how far down the stack has
//! reached since. Only built for the Cortex-M target (cortex-m-rt's memory layout: statics at the
//! bottom of RAM, the stack growing down from its top).
//!
//! The figure is a high-water mark of what ran, not a bound; [`overflowed`] says whether the
//! stack reached the statics (the words just above them were overwritten).

use core::ptr::{addr_of, addr_of_mut};

/// The pattern painted on free RAM.
const PAINT: u32 = 0xDEAD_BEEF;

/// Words below the current stack pointer left unpainted (the painting function's own frame).
const GUARD_WORDS: usize = 64;

unsafe extern "C" {
    /// cortex-m-rt: the first word after `.bss`/`.uninit` (where a heap would start).
    static mut __sheap: u32;
    /// cortex-m-rt: the initial stack pointer (top of the stack).
    static _stack_start: u32;
}

fn bounds() -> (*mut u32, usize) {
    let bottom = addr_of_mut!(__sheap);
    let top = addr_of!(_stack_start) as usize;
    (bottom, top)
}

/// Paints the free stack. Call once, early in `main`, before anything deep runs.
pub fn paint() {
    let (bottom, _) = bounds();
    let sp = cortex_m::register::msp::read() as usize;
    let end = sp.saturating_sub(GUARD_WORDS * 4);
    let mut p = bottom;
    while (p as usize) < end {
        // SAFETY: `[__sheap, sp - guard)` is RAM that no static occupies (cortex-m-rt places
        // nothing there) and that the stack has not reached yet; volatile so the stores are kept.
        unsafe {
            p.write_volatile(PAINT);
            p = p.add(1);
        }
    }
}

/// The lowest address the stack has written since [`paint`], as bytes of stack used.
pub fn peak_bytes() -> u32 {
    let (bottom, top) = bounds();
    let mut p = bottom;
    // SAFETY: reads of the painted region, which lies below the live stack.
    while (p as usize) < top && unsafe { p.read_volatile() } == PAINT {
        p = p.wrapping_add(1);
    }
    u32::try_from(top - p as usize).unwrap_or(u32::MAX)
}

/// Whether the stack reached the end of the statics.
pub fn overflowed() -> bool {
    let (bottom, _) = bounds();
    // SAFETY: one read of the first free word.
    unsafe { bottom.read_volatile() != PAINT }
}
