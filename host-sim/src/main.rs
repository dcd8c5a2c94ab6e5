//! `ferroslam-sim`: replay, evaluate and demo ferroslam on the host.

fn main() -> std::process::ExitCode {
    ferroslam_sim::commands::main()
}
