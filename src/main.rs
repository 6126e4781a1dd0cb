//! The `cso` command: a thin shell over the library. `main` parses the
//! arguments, starts MPI under `mpirun`, and hands each command to its `run`
//! in [`cli`], which prints what the library returns; the exit code is the
//! outcome's (0 success, 1 errors in a scene, 2 I/O or usage errors, 130 interrupted).

mod cli;

use clap::Parser;
use cli::args::{Cli, Command, StudyCommand};
use cli::print::{fail, EXIT_IO};
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = Cli::parse();
    let (ranks, _universe) = match cli::ranks::start_mpi() {
        Ok(r) => r,
        Err(code) => return ExitCode::from(code),
    };
    cli::print::set_quiet(cli.quiet || cli::print::muted());
    let opts = cli.check_options();
    let outcome = match &cli.command {
        Command::Solve(c) => c.run(&opts, &ranks),
        Command::Sensitivity(c) => c.run(&opts, &ranks),
        Command::Optimize(c) => c.run(&opts, &ranks),
        Command::Bench(c) if c.runs_distributed(&ranks) => c.run_on(&ranks),
        _ if ranks.as_ref().is_some_and(|c| c.size() > 1) => Err(fail(
            EXIT_IO,
            "only `cso solve`, `cso sensitivity`, `cso optimize` and `cso bench traffic` run distributed over MPI ranks; run this command without mpirun",
        )),
        Command::Check(c) => c.run(&opts),
        Command::Compare(c) => c.run(&opts),
        Command::Bench(c) => c.run(),
        Command::Study(StudyCommand::Convergence(c)) => c.run(&opts),
        Command::Study(StudyCommand::Tolerance(c)) => c.run(&opts),
        Command::Compile(c) => c.run(&opts),
        Command::Export(c) => c.run(&opts),
        Command::Fmt(c) => c.run(),
        Command::Lsp => cli::lsp::run(),
    };
    let listed = cli::job::close_outputs();
    // `_universe` (MPI's) lives to the end of `main`: dropping it finalizes MPI.
    match outcome.and(listed) {
        Ok(()) => ExitCode::SUCCESS,
        Err(code) => ExitCode::from(code),
    }
}
