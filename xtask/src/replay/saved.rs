//! The map a firmware run saved to its flash region against the host's, and the map files both
//! sides are compared as (shared with the fuzz targets).

use std::fs;
use std::path::Path;

use anyhow::{Context, Result, anyhow, bail};
use ferroslam_core::ar::{SavedWorld, World};
use ferroslam_core::loops::PlaceMemory;
use ferroslam_core::map::KeyframeStore;
use ferroslam_core::persist::{FlashStore, SliceFlash};
use ferroslam_sim::map_file::MapFile;

use super::{FLASH_IMAGE, HOST_MAP};
use crate::firmware;

/// The address of the firmware's flash region for the long-term store (`__place_store_start`
/// of memory-qemu-mps2.x), where a flash image is loaded for a second boot.
pub(super) fn place_store_address(elf: &Path) -> Result<u64> {
    let symbols = firmware::nm(elf, &[])?;
    symbols
        .lines()
        .find(|l| l.ends_with(" __place_store_start"))
        .and_then(|l| u64::from_str_radix(l.split_whitespace().next()?, 16).ok())
        .ok_or_else(|| anyhow!("no __place_store_start symbol in {}", elf.display()))
}

/// The map in the firmware's flash image (`flash.bin`: what a boot on it finds, written as a map
/// file) against the host's saved map (`host-map.fsmp`), byte for byte: `Ok(summary)` when
/// equal, `Err` naming the first differing byte.
pub(super) fn compare_saved_maps(out: &Path) -> Result<Result<String>> {
    let mut image = fs::read(out.join(FLASH_IMAGE))
        .with_context(|| format!("the firmware wrote no {FLASH_IMAGE}"))?;
    let board = map_in_flash_image(&mut image)?;
    let host = fs::read(out.join(HOST_MAP)).with_context(|| format!("reading {HOST_MAP}"))?;
    if board == host {
        let map = MapFile::from_bytes(&board).context("the board's map")?;
        let (planes, anchors) =
            map.world.as_ref().map_or((0, 0), |w| (w.planes().len(), w.anchors().len()));
        return Ok(Ok(format!(
            "the map in the board's flash image is the host's byte for byte ({} keyframes, \
             {planes} planes, {anchors} anchors, {} bytes as a map file)",
            map.records.len(),
            board.len()
        )));
    }
    let at =
        board.iter().zip(&host).position(|(a, b)| a != b).unwrap_or(board.len().min(host.len()));
    fs::write(out.join("board-map.fsmp"), &board)?;
    Ok(Err(anyhow!(
        "the board's saved map differs from the host's: {} against {} bytes, first difference at \
         byte {at} (board-map.fsmp and {HOST_MAP} in {})",
        board.len(),
        host.len(),
        out.display()
    )))
}

/// The map a boot on the flash image `image` finds, as a map file ([`ferroslam_core::persist`]):
/// its records, then its planes and anchors when it holds them.
fn map_in_flash_image(image: &mut [u8]) -> Result<Vec<u8>> {
    let store = FlashStore::mount(SliceFlash::new(image))
        .map_err(|e| anyhow!("mounting the flash image: {e:?}"))?;
    let mut memory = PlaceMemory::new(FlashStore::unmounted(SliceFlash::empty()), 0);
    memory.attach(store);
    if memory.stats().store_errors > 0 {
        bail!("{} records in the flash image do not decode", memory.stats().store_errors);
    }
    let saved = memory.held_world().transpose().map_err(|e| anyhow!("flash image: {e}"))?;
    saved_map(&mut memory, saved.as_ref()).context("reading the flash image's map")
}

/// The map file `memory` saves, with `world` (planes and anchors read back) after its records:
/// what a memory that loaded or booted that map saves again, byte for byte.
///
/// # Errors
/// A record the store cannot give.
pub fn saved_map<S: KeyframeStore>(
    memory: &mut PlaceMemory<S>,
    world: Option<&SavedWorld>,
) -> Result<Vec<u8>> {
    let parts = world.map(SavedWorld::restored);
    let world = parts.as_ref().map(|(planes, anchors)| World { planes, anchors });
    let mut file = Vec::new();
    memory
        .save(world.as_ref(), |b: &[u8]| -> Result<(), std::convert::Infallible> {
            file.extend_from_slice(b);
            Ok(())
        })
        .map_err(|e| anyhow!("{e:?}"))?;
    Ok(file)
}
