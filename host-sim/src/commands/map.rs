//! `ferroslam-sim map info FILE` and `map export FILE --ply OUT`: a saved map file (`replay
//! --save-map`) summarized, or written out as a point cloud a viewer opens.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};

use crate::map_file::MapFile;

/// Arguments of `map`.
#[derive(Debug, Args)]
pub struct MapArgs {
    /// What to do with the map file.
    #[command(subcommand)]
    pub action: MapAction,
}

/// The actions of `map`.
#[derive(Debug, Subcommand)]
pub enum MapAction {
    /// Print what a map file holds: format version, size, checksum, keyframes, verification
    /// points per keyframe, timestamp span and the extent of the keyframe positions (metres,
    /// world frame). The whole file is checked first, as `replay --load-map` checks it.
    Info {
        /// A map file written by `replay --save-map`.
        file: PathBuf,
    },
    /// Write a map file as an ASCII PLY point cloud (MeshLab, CloudCompare): the verification
    /// points in the world frame (metres) in grey, the keyframes' camera positions in red.
    Export {
        /// A map file written by `replay --save-map`.
        file: PathBuf,
        /// The PLY file to write (replaced if it exists; not written if the map is refused).
        #[arg(long, value_name = "OUT")]
        ply: PathBuf,
    },
}

/// Runs `map`: the summary, or the PLY and its vertex count, on stdout.
///
/// # Errors
/// A map file that cannot be read or is refused (the message says what is wrong with it); a PLY
/// that cannot be written.
pub fn run(args: &MapArgs) -> Result<()> {
    match &args.action {
        MapAction::Info { file } => {
            let map = MapFile::read(file)?;
            println!("map {}", file.display());
            for line in map.summary().to_string().lines() {
                println!("  {line}");
            }
        }
        MapAction::Export { file, ply } => {
            let map = MapFile::read(file)?;
            let out = std::fs::File::create(ply)
                .with_context(|| format!("cannot create {}", ply.display()))?;
            let counts =
                map.write_ply(out).with_context(|| format!("writing {}", ply.display()))?;
            println!(
                "map {}: wrote {} vertices to {} ({} verification points, {} keyframe camera \
                 positions, {} plane centroids, {} anchors)",
                file.display(),
                counts.vertices(),
                ply.display(),
                counts.points,
                counts.cameras,
                counts.planes,
                counts.anchors
            );
            if counts.skipped > 0 {
                eprintln!(
                    "note: {} vertices with a non-finite coordinate left out",
                    counts.skipped
                );
            }
        }
    }
    Ok(())
}
