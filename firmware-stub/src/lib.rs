//! ferroslam-firmware: board-independent wiring of ferroslam-core (being written).
#![no_std]
