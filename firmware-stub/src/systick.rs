//! A tick clock on the Cortex-M SysTick timer, for per-frame cost figures. Only built for the
//! Cortex-M target.
//!
//! SysTick counts down from a 24-bit reload on the core clock; its wrap interrupt
//! ([`on_systick_wrap`], called from the binary's `SysTick` handler) extends it to 32 bits. Under
//! QEMU with `-icount shift=0` the mps2-an386 core clock is 25 MHz against one instruction per
//! virtual nanosecond: one tick is 40 instructions, exactly and deterministically.

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;
use ferroslam_core::wire::TickUnit;

use crate::pipeline::TickClock;

/// SysTick's reload: the full 24-bit range.
const RELOAD: u32 = 0x00FF_FFFF;

/// Wraps of SysTick since [`SysTickClock::start`].
static WRAPS: AtomicU32 = AtomicU32::new(0);

/// Call from the `SysTick` exception handler: counts one wrap.
pub fn on_systick_wrap() {
    WRAPS.fetch_add(1, Ordering::Relaxed);
}

/// SysTick as a 32-bit tick clock of `INSTRUCTIONS_PER_TICK` instructions per tick (40 under
/// QEMU's `-icount shift=0`).
pub struct SysTickClock<const INSTRUCTIONS_PER_TICK: u16> {
    /// Owned so that nothing else reconfigures the timer.
    _syst: SYST,
}

impl<const N: u16> core::fmt::Debug for SysTickClock<N> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "SysTickClock<{N} instructions per tick>")
    }
}

impl<const N: u16> SysTickClock<N> {
    /// Starts SysTick free-running on the core clock with its wrap interrupt on.
    pub fn start(mut syst: SYST) -> Self {
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(RELOAD);
        syst.clear_current();
        WRAPS.store(0, Ordering::Relaxed);
        syst.enable_interrupt();
        syst.enable_counter();
        // The counter reads 0 until its first reload; from then on it counts down from RELOAD.
        // Waiting for it makes the first reading consistent with the later ones.
        while SYST::get_current() == 0 {}
        Self { _syst: syst }
    }
}

impl<const N: u16> TickClock for SysTickClock<N> {
    const UNIT: TickUnit = TickUnit::Instructions { per_tick: N };

    fn now(&mut self) -> u32 {
        loop {
            let wraps = WRAPS.load(Ordering::Relaxed);
            let down = SYST::get_current();
            // A wrap between the two reads would pair the new count with the old wrap number.
            if WRAPS.load(Ordering::Relaxed) == wraps {
                return (wraps << 24).wrapping_add(RELOAD - down);
            }
        }
    }
}
