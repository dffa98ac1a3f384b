//! `translucent generate`: shell completions and man pages, made from the command-line
//! definition itself so that they cannot drift from it.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Subcommand;

/// What to generate.
#[derive(Subcommand)]
pub enum GenerateCommand {
    /// Shell completions, written to standard output (e.g. `translucent generate completions
    /// bash > ~/.local/share/bash-completion/completions/translucent`).
    Completions {
        /// The shell.
        shell: clap_complete::Shell,
    },
    /// Man pages, one per command and subcommand (translucent.1, translucent-optimize.1, …).
    Man {
        /// Folder for the pages (created if missing); view one with `man -l OUT/translucent.1`.
        #[arg(long, default_value = "out/man")]
        out: PathBuf,
        /// Replace pages already in the folder.
        #[arg(long)]
        overwrite: bool,
    },
}

/// Runs `generate` for the command line `cmd` (the whole `translucent` command).
pub fn run(g: &GenerateCommand, mut cmd: clap::Command) -> Result<()> {
    match g {
        GenerateCommand::Completions { shell } => {
            let name = cmd.get_name().to_string();
            clap_complete::generate(*shell, &mut cmd, name, &mut std::io::stdout());
            Ok(())
        }
        GenerateCommand::Man { out, overwrite } => {
            std::fs::create_dir_all(out)
                .with_context(|| format!("cannot create {}", out.display()))?;
            if !overwrite && let Some(p) = existing_page(out)? {
                bail!(
                    "{} already holds man pages ({}); pass --overwrite to replace them",
                    out.display(),
                    p.display()
                );
            }
            clap_mangen::generate_to(without_help_subcommands(cmd), out)
                .with_context(|| format!("cannot write man pages into {}", out.display()))?;
            let n = std::fs::read_dir(out)?
                .filter_map(|e| e.ok())
                .filter(|e| is_page(&e.path()))
                .count();
            println!(
                "wrote {n} man pages into {} (man -l {}/translucent.1)",
                out.display(),
                out.display()
            );
            Ok(())
        }
    }
}

/// The command tree without clap's `help` subcommands (no page of their own).
fn without_help_subcommands(cmd: clap::Command) -> clap::Command {
    cmdline::for_every_command(cmd, &|c| c.disable_help_subcommand(true))
}

fn is_page(p: &Path) -> bool {
    p.extension().is_some_and(|e| e == "1")
        && p.file_name()
            .and_then(|n| n.to_str())
            .is_some_and(|n| n.starts_with("translucent"))
}

fn existing_page(dir: &Path) -> Result<Option<PathBuf>> {
    for e in std::fs::read_dir(dir).with_context(|| format!("cannot read {}", dir.display()))? {
        let p = e?.path();
        if is_page(&p) {
            return Ok(Some(p));
        }
    }
    Ok(None)
}
