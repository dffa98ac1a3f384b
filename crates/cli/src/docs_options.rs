//! The command lines quoted in README.md and docs/commands.md name options that exist: a test,
//! so that the documentation cannot go stale when an option is renamed or removed.

use std::collections::BTreeSet;

use clap::Command;

/// Long option names (and their aliases) of `cmd`, with the global options of the root.
fn options_of(cmd: &Command, globals: &BTreeSet<String>) -> BTreeSet<String> {
    let mut s = globals.clone();
    for a in cmd.get_arguments() {
        if let Some(l) = a.get_long() {
            s.insert(l.to_string());
        }
        if let Some(al) = a.get_all_aliases() {
            s.extend(al.into_iter().map(String::from));
        }
    }
    s.insert("help".into());
    s
}

/// Every option anywhere under `cmd`.
fn all_options(cmd: &Command, globals: &BTreeSet<String>, out: &mut BTreeSet<String>) {
    out.extend(options_of(cmd, globals));
    for s in cmd.get_subcommands() {
        all_options(s, globals, out);
    }
}

/// The quoted command lines of a Markdown text: inline code spans and the lines of fenced
/// blocks, each with the command of the section it stands in (a heading "## `optimize`").
fn snippets(text: &str) -> Vec<(Option<String>, String, usize)> {
    let mut out = Vec::new();
    let mut section: Option<String> = None;
    let mut fenced = false;
    for (i, line) in text.lines().enumerate() {
        if line.starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            out.push((section.clone(), line.to_string(), i + 1));
            continue;
        }
        if let Some(h) = line.strip_prefix("## ") {
            section = h
                .split('`')
                .nth(1)
                .map(|c| c.split_whitespace().next().unwrap_or("").to_string());
        }
        for (k, span) in line.split('`').enumerate() {
            if k % 2 == 1 {
                out.push((section.clone(), span.to_string(), i + 1));
            }
        }
    }
    out
}

/// The options of `snippet` that `root` lacks, as "--name (in `command`)".
fn unknown_options(root: &Command, section: Option<&str>, snippet: &str) -> Vec<String> {
    let globals: BTreeSet<String> = root
        .get_arguments()
        .filter(|a| a.is_global_set())
        .filter_map(|a| a.get_long().map(String::from))
        .collect();
    let mut everywhere = BTreeSet::new();
    all_options(root, &globals, &mut everywhere);
    let tokens: Vec<&str> = snippet.split_whitespace().collect();
    let Some(&first) = tokens.first() else {
        return Vec::new();
    };
    // Where the command line starts: `translucent …`, `cargo run --release -- …`, a bare
    // subcommand, or bare options (of the section's command).
    let start = if first == "translucent" {
        1
    } else if first == "cargo" {
        match tokens.iter().position(|t| *t == "--") {
            Some(p) => p + 1,
            None => return Vec::new(),
        }
    } else if root.find_subcommand(first).is_some() || first.starts_with("--") {
        0
    } else {
        return Vec::new();
    };
    let mut cur: Option<&Command> = if first.starts_with("--") {
        section.and_then(|s| root.find_subcommand(s))
    } else {
        Some(root)
    };
    let mut bad = Vec::new();
    for t in &tokens[start..] {
        if let Some(c) = cur
            && let Some(sub) = c.find_subcommand(t)
        {
            cur = Some(sub);
            continue;
        }
        let Some(name) = t.strip_prefix("--") else {
            continue;
        };
        let name: String = name
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
            .collect();
        if name.is_empty() {
            continue;
        }
        let known = match cur {
            Some(c) => {
                let mut under = BTreeSet::new();
                all_options(c, &globals, &mut under);
                under.contains(&name)
            }
            None => everywhere.contains(&name),
        };
        if !known {
            bad.push(format!(
                "--{name} (in `{}`)",
                cur.map_or("any command".to_string(), |c| c.get_name().to_string())
            ));
        }
    }
    bad
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    use super::*;

    #[test]
    fn every_option_the_docs_name_exists() {
        let root = crate::Cli::command();
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let mut bad = Vec::new();
        for file in ["README.md", "docs/commands.md"] {
            let text = std::fs::read_to_string(dir.join(file)).unwrap();
            let found = snippets(&text);
            assert!(found.len() > 10, "{file}: too few command lines found");
            for (section, s, line) in found {
                for b in unknown_options(&root, section.as_deref(), &s) {
                    bad.push(format!("{file}:{line}: {b} in `{s}`"));
                }
            }
        }
        assert!(
            bad.is_empty(),
            "options the docs name but the CLI lacks:\n{}",
            bad.join("\n")
        );
    }

    #[test]
    fn a_renamed_option_is_caught() {
        let root = crate::Cli::command();
        assert!(unknown_options(&root, None, "translucent optimize --dataset d").is_empty());
        assert!(unknown_options(&root, None, "cargo run --release -- demo --seed 3").is_empty());
        assert_eq!(
            unknown_options(&root, None, "translucent optimize --no-such-flag"),
            vec!["--no-such-flag (in `optimize`)"]
        );
        // An option of another command.
        assert_eq!(
            unknown_options(&root, None, "translucent demo --dataset d").len(),
            1
        );
        // Bare options belong to the section's command.
        assert!(unknown_options(&root, Some("optimize"), "--starts N").is_empty());
        assert_eq!(
            unknown_options(&root, Some("compare"), "--starts N").len(),
            1
        );
        // Other programs are not ours to check.
        assert!(unknown_options(&root, None, "pip install --upgrade mitsuba").is_empty());
    }
}
