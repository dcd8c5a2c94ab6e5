//! QEMU mps2-an386 binary (being written).
#![no_std]
#![no_main]
