//! The `voxcast` command: parses arguments and wires the library together.
//! No rendering logic lives here: `args/` holds each subcommand's flags and
//! help, `cmd/` each subcommand's body; this file dispatches.

mod args;
mod cmd;

use args::{Cli, Command};
use clap::Parser;

fn main() {
    let cli = Cli::parse();
    quiet_on_closed_pipe(&cli.command);
    one_arena_for_stores(&cli.command);
    // One command per process: no output may replace a file it read.
    voxcast::files::record_inputs();
    // WRF, MINC-2 and JPEG-LS, where this build has them (features).
    voxcast_native_io::install();
    // Started by mpirun: `render` is split over the processes.
    #[cfg(feature = "mpi")]
    let universe = cmd::mpi::start();
    #[cfg(feature = "mpi")]
    if let Some(world) = universe.as_ref().map(|u| u.world()) {
        use mpi::topology::Communicator;
        let result = match &cli.command {
            Command::Render(a) => Some(cmd::mpi::render(a, &world)),
            Command::Animate(a) => Some(cmd::mpi::animate(a, &world)),
            Command::Bench(a) => Some(cmd::mpi::bench(a, &world)),
            _ if world.size() == 1 => None,
            _ => Some(Err(anyhow::anyhow!(
                "under mpirun, voxcast runs `render` and `bench` (the volume split over the processes) and `animate` (the frames shared among them) only; run other commands without mpirun"
            ))),
        };
        match result {
            Some(Ok(())) => return,
            Some(Err(e)) => cmd::mpi::fail(&world, &e),
            None => {}
        }
    }
    let result = match cli.command {
        Command::Render(a) => cmd::render::run(*a),
        Command::Bench(a) => cmd::bench::run(*a),
        Command::Info(a) => cmd::info::run(a),
        Command::Compare(a) => cmd::compare::run(a),
        Command::Convert(a) => cmd::convert::run(*a),
        Command::Cloud(a) => cmd::cloud::run(*a),
        Command::Presets => {
            cmd::presets::run();
            Ok(())
        }
        Command::Simulate(a) => cmd::simulate::run(a),
        Command::Animate(a) => cmd::animate::run(*a),
        Command::BenchFrames(a) => cmd::bench_frames::run(*a),
        Command::View(a) => cmd::view::run(*a),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

/// Commands that only print (`info`, `presets`, `compare`) end quietly when
/// their reader goes away (`voxcast info scan.nrrd | head`), as other Unix
/// tools do; Rust ignores SIGPIPE, and `println!` into the closed pipe would
/// panic. Commands that write files keep it ignored: they finish (or fail)
/// and clean up their temporary files.
fn quiet_on_closed_pipe(c: &Command) {
    #[cfg(unix)]
    if matches!(c, Command::Info(_) | Command::Presets | Command::Compare(_)) {
        // SAFETY: sets one signal's action back to the default, before
        // any thread is started.
        unsafe { libc::signal(libc::SIGPIPE, libc::SIG_DFL) };
    }
    #[cfg(not(unix))]
    let _ = c;
}

/// A render of a chunked store decodes chunks on several threads and frees
/// them as its cache evicts them; glibc's per-thread arenas then keep the
/// freed chunks' pages, and a render under `--memory-budget 2GiB` peaked at
/// 2.9 GiB resident. With one arena it peaks at 2.28 GiB, and it was no
/// slower (see docs/outofcore.md). Elsewhere one arena cost 3–7 % (the
/// bench's parallel loading), so only renders of a store get it. Set
/// before any thread starts.
fn one_arena_for_stores(c: &Command) {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    if let Command::Render(a) = c {
        let store = a
            .scene
            .input
            .as_deref()
            .is_some_and(|p| voxcast::io::zarr::is_zarr(std::path::Path::new(p)));
        if store {
            // SAFETY: a malloc tunable, set before any thread is started.
            unsafe { libc::mallopt(libc::M_ARENA_MAX, 1) };
        }
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    let _ = c;
}
