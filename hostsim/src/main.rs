//! The `voxcube` command.

fn main() -> std::process::ExitCode {
    voxcube::cli::main()
}
