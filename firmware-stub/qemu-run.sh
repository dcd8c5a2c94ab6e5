#!/usr/bin/env bash
# Runs a firmware ELF on QEMU's mps2-an386 board (Cortex-M4F) with semihosting. It is the cargo
# runner for thumbv7em-none-eabihf (see .cargo/config.toml), and works by hand too:
#
#   firmware-stub/qemu-run.sh ELF [ARGS...]
#
# For qemu-mps2 (ref-board is for the reference board's memory map, not for QEMU): ARGS are
# `FRAMES fx fy cx cy width height` (see src/bin/qemu-mps2/main.rs) and become the firmware's
# semihosting command line (QEMU `-append`); file paths are relative to the current directory
# (QEMU's, with `target=native` semihosting).
#
# Channels: QEMU's stdout carries only the binary defmt stream (the semihosting console); UART0
# (the wire messages) goes to the file $QEMU_UART (default uart.bin; decode it with
# `ferroslam-sim decode-serial`); the monitor is off, QEMU's own messages go to stderr. The
# defmt stream is decoded live with `defmt-print` when it is on PATH; otherwise it is saved next
# to the ELF and the command that decodes it is printed (`cargo xtask firmware-replay` decodes it
# itself, nothing to install).
#
# `-icount shift=0,align=off,sleep=off`: one emulated instruction per virtual nanosecond, so
# SysTick (25 MHz core clock) advances once per 40 instructions and the firmware's tick counts are
# deterministic.
#
# Exit status: the firmware's (semihosting exit: 0 success, 1 failure), 124 on timeout
# (QEMU_TIMEOUT_S, default 60 s).
set -uo pipefail

elf=${1:?usage: qemu-run.sh ELF [FRAMES fx fy cx cy width height]}
shift
qemu=(timeout "${QEMU_TIMEOUT_S:-60}" qemu-system-arm
    -M mps2-an386 -cpu cortex-m4 -nographic -monitor none -serial "file:${QEMU_UART:-uart.bin}"
    -semihosting-config enable=on,target=native -icount shift=0,align=off,sleep=off
    -kernel "$elf")
if (($#)); then
    qemu+=(-append "$*")
fi

if command -v defmt-print >/dev/null 2>&1; then
    "${qemu[@]}" | defmt-print -e "$elf"
    status=${PIPESTATUS[0]}
else
    log="$elf.defmt"
    "${qemu[@]}" >"$log"
    status=$?
    echo "qemu-run: defmt log saved to $log ($(wc -c <"$log") bytes); decode it with" >&2
    echo "  defmt-print -e $elf < $log    (defmt-print: cargo install defmt-print)" >&2
fi
echo "qemu-run: firmware exit status $status" >&2
exit "$status"
