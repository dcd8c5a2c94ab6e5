//! The CLI's subcommands (being written by the integrator; see `main`).

/// Entry point of the `ferroslam-sim` binary.
pub fn main() -> std::process::ExitCode {
    std::process::ExitCode::FAILURE
}
