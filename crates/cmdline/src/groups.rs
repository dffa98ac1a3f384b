//! The options that many commands take, each defined once: the seed ([`Seed`]), the output
//! folder ([`Output`]) and the permission to replace outputs ([`Overwrite`]), the render budget
//! ([`Views`], [`Resolution`], [`Spp`]) and the experiments' smoke-test scale ([`Quick`]).
//!
//! A command flattens a group (`#[command(flatten)] pub seed: Seed`) and reads it through
//! `Deref` (`*args.seed`, `args.out.join(…)`). Where a command's default or its help differs
//! from the group's, the command says so at its own definition with [`default_and_help`] or
//! [`help`] (`#[command(mut_arg("seed", default_and_help("1", "Seed of …")))]`), so that the
//! option's name, type and parsing stay in one place.

use std::ops::Deref;
use std::path::PathBuf;

use clap::Arg;
use clap::builder::OsStr;

/// `--seed`: the base seed of a command's random streams.
#[derive(clap::Args, Clone, Copy, Debug, PartialEq, Eq)]
pub struct Seed {
    /// Seed of every random stream (the same seed and thread count give the same output).
    #[arg(id = "seed", long = "seed", value_name = "SEED", default_value_t = 0)]
    value: u64,
}

impl Deref for Seed {
    type Target = u64;
    fn deref(&self) -> &u64 {
        &self.value
    }
}

/// `--out`: the folder a command writes into. Required, unless the command gives it a default.
#[derive(clap::Args, Clone, Debug, PartialEq, Eq)]
pub struct Output {
    /// Output folder.
    #[arg(id = "out", long = "out", value_name = "OUT")]
    dir: PathBuf,
}

impl Deref for Output {
    type Target = PathBuf;
    fn deref(&self) -> &PathBuf {
        &self.dir
    }
}

impl From<PathBuf> for Output {
    fn from(dir: PathBuf) -> Self {
        Self { dir }
    }
}

impl From<u64> for Seed {
    fn from(value: u64) -> Self {
        Self { value }
    }
}

impl From<bool> for Overwrite {
    fn from(allowed: bool) -> Self {
        Self { allowed }
    }
}

impl AsRef<std::path::Path> for Output {
    fn as_ref(&self) -> &std::path::Path {
        &self.dir
    }
}

/// `--overwrite`: files already in the output folder may be replaced (never without it).
#[derive(clap::Args, Clone, Copy, Debug, PartialEq, Eq)]
pub struct Overwrite {
    /// Replace existing outputs.
    #[arg(id = "overwrite", long = "overwrite")]
    allowed: bool,
}

impl Deref for Overwrite {
    type Target = bool;
    fn deref(&self) -> &bool {
        &self.allowed
    }
}

/// `--views`: how many views a command renders or uses.
#[derive(clap::Args, Clone, Copy, Debug, PartialEq, Eq)]
pub struct Views {
    /// Number of views.
    #[arg(id = "views", long = "views", value_name = "VIEWS")]
    count: usize,
}

/// `--res`: the width and height of square images.
#[derive(clap::Args, Clone, Copy, Debug, PartialEq, Eq)]
pub struct Resolution {
    /// Image width and height in pixels.
    #[arg(id = "res", long = "res", value_name = "RES")]
    pixels: u32,
}

/// `--spp`: samples per pixel of a command's renders.
#[derive(clap::Args, Clone, Copy, Debug, PartialEq, Eq)]
pub struct Spp {
    /// Samples per pixel.
    #[arg(id = "spp", long = "spp", value_name = "SPP")]
    samples: u32,
}

/// `--quick`: an experiment at a scale that finishes in seconds, a smoke test of its pipeline.
#[derive(clap::Args, Clone, Copy, Debug, PartialEq, Eq)]
pub struct Quick {
    /// A smoke test in seconds: not a measurement.
    #[arg(id = "quick", long = "quick")]
    on: bool,
}

macro_rules! value_of {
    ($($group:ty => $field:ident: $t:ty),*) => {$(
        impl Deref for $group {
            type Target = $t;
            fn deref(&self) -> &$t {
                &self.$field
            }
        }
        impl From<$t> for $group {
            fn from($field: $t) -> Self {
                Self { $field }
            }
        }
    )*};
}

value_of!(Views => count: usize, Resolution => pixels: u32, Spp => samples: u32, Quick => on: bool);

/// A command's own default and help of a flattened group's option (its value parsed as the
/// group parses it; a required option becomes optional).
pub fn default_and_help(default: impl Into<OsStr>, text: &'static str) -> impl FnOnce(Arg) -> Arg {
    let default = default.into();
    move |a| a.default_value(default).required(false).help(text)
}

/// A command's own default of a flattened group's option (a required option becomes optional).
pub fn default(value: impl Into<OsStr>) -> impl FnOnce(Arg) -> Arg {
    let value = value.into();
    move |a| a.default_value(value).required(false)
}

/// A command's own help of a flattened group's option.
pub fn help(text: &'static str) -> impl FnOnce(Arg) -> Arg {
    move |a| a.help(text)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser, Debug)]
    #[command(
        mut_arg("out", default_and_help("out/x", "Where x goes.")),
        mut_arg("seed", default_and_help("3", "Seed of x."))
    )]
    struct X {
        #[command(flatten)]
        out: Output,
        #[command(flatten)]
        seed: Seed,
        #[command(flatten)]
        overwrite: Overwrite,
    }

    #[derive(Parser, Debug)]
    struct Y {
        #[command(flatten)]
        out: Output,
        #[command(flatten)]
        seed: Seed,
    }

    #[test]
    fn a_command_sets_its_own_defaults_and_help() {
        let x = X::try_parse_from(["x"]).unwrap();
        assert_eq!(x.out.as_path(), std::path::Path::new("out/x"));
        assert_eq!(*x.seed, 3);
        assert!(!*x.overwrite);
        let x = X::try_parse_from(["x", "--out", "o", "--seed", "7", "--overwrite"]).unwrap();
        assert_eq!(
            (x.out.as_path(), *x.seed, *x.overwrite),
            (std::path::Path::new("o"), 7, true)
        );
        let help = <X as clap::CommandFactory>::command()
            .render_help()
            .to_string();
        assert!(
            help.contains("Where x goes.") && help.contains("[default: out/x]"),
            "{help}"
        );
        assert!(
            help.contains("Seed of x.") && help.contains("[default: 3]"),
            "{help}"
        );
    }

    #[test]
    fn without_a_default_the_output_folder_is_required() {
        let e = Y::try_parse_from(["y"]).unwrap_err();
        assert_eq!(e.kind(), clap::error::ErrorKind::MissingRequiredArgument);
        let y = Y::try_parse_from(["y", "--out", "o"]).unwrap();
        assert_eq!(*y.seed, 0);
        assert!(Y::try_parse_from(["y", "--out", "o", "--seed", "-1"]).is_err());
    }
}
