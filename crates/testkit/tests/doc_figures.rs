//! README's headline figures against BENCHMARKS.md.
//!
//! README.md's "Results" section quotes figures (seconds per iteration, accuracy medians,
//! calibration, …) whose commands, dates and data are in BENCHMARKS.md. This test protects them
//! from drifting apart: for every quoted figure it checks that README's Results section still
//! contains the quoting text, and that the BENCHMARKS.md section it comes from (from its heading
//! to the next heading of the same or a higher level) contains the same number. When a benchmark
//! is run again, update BENCHMARKS.md, README.md and the table below together.
//!
//! Reads only the two files; no build artefacts, no timing.

use std::path::PathBuf;

/// (text in README's Results section, BENCHMARKS.md heading, the number both must contain).
/// The number must also occur in the README text, so that the README quotes exactly it.
const FIGURES: &[(&str, &str, &str)] = &[
    // Speed of one iteration at the paper's workload.
    ("learned 1.26 s", RECOVERY_SPEED, "1.26"),
    ("(the paper: 1.40 s, RTX 4090)", RECOVERY_SPEED, "1.40"),
    ("volumetric 1.51 s", RECOVERY_SPEED, "1.51"),
    ("**defaults 2.14 s**", RECOVERY_SPEED, "2.14"),
    ("(1.41 s over the first iterations)", RECOVERY_SPEED, "1.41"),
    ("Mitsuba 3 PRB 4.17 s", RECOVERY_SPEED, "4.17"),
    ("(8.43 s over a recovery)", RECOVERY_SPEED, "8.43"),
    // The time to an accurate answer.
    ("**defaults 11.7 s**", TIME_TO_ACCURACY, "11.7"),
    (
        "same learning rates 8.0 s (0.87×",
        TIME_TO_ACCURACY,
        "0.87×",
    ),
    (
        "then the tracer, 5.0 s (2.3× sooner",
        TIME_TO_ACCURACY,
        "2.3×",
    ),
    // The paper's accuracy experiment.
    ("median σ_t error 4.1 %", ACCURACY, "4.1 %"),
    ("α 0.0028", ACCURACY, "0.0028"),
    // The robustness suite, the defaults.
    ("in 99 % of pairs", ROBUSTNESS, "99 %"),
    ("σ_t determined in 15 of 36 pairs", ROBUSTNESS, "15 of 36"),
    ("15 of 36 pairs, median error 0.9 %", ROBUSTNESS, "0.9 %"),
    ("(largest 3.6 %)", ROBUSTNESS, "3.6 %"),
    ("median σ_t error 1.9 %", ROBUSTNESS, "1.9 %"),
    ("2 of 48 runs `failed`", ROBUSTNESS, "2 of 48"),
    ("(σ_t: 20 of 21", ROBUSTNESS, "20 of 21"),
    // The Python package against the binary.
    ("`render` 0.93×", PYTHON, "0.93"),
    ("`optimize` 0.95×", PYTHON, "0.95"),
    ("fresh clone 5 min 31 s", PYTHON, "5 min 31 s"),
    // The volumetric baseline.
    ("σ_t determined in 30 of 72 pairs", VOLUMETRIC, "30 of 72"),
    ("30 of 72 pairs, median error 0.6 %", VOLUMETRIC, "0.6 %"),
    ("94 % calibration", VOLUMETRIC, "94 %"),
    ("[1.51 s per iteration]", RECOVERY_SPEED, "1.51"),
    ("3.06 s at α ≈ 0.97", RECOVERY_SPEED, "3.06"),
    ("iterations cost 1.1× the defaults'", RECOVERY_SPEED, "1.1×"),
    ("1.4× their average over a", RECOVERY_SPEED, "1.4×"),
    // The dielectric, forward-scattering cases at reduced scale.
    (
        "none of 27 pairs (median error 16.8 %",
        DIELECTRIC,
        "16.8 %",
    ),
    ("none of 27 pairs", DIELECTRIC, "none of 27"),
    ("7 of 9 runs report", DIELECTRIC, "7 of 9"),
    ("(median error 30.1 %, 28.2 % before)", DIELECTRIC, "30.1 %"),
    ("rendered them 5–210 % off", DIELECTRIC, "5–210 %"),
    // The learned model over g, η and roughness.
    ("within 3 % at g = 0", LEARNED_GN, "3 %"),
    ("up to 16 % off at g 0.9", LEARNED_GN, "16"),
    ("(median error 17.7 %)", DIELECTRIC, "17.7 %"),
    (
        "the six do better (median error 19.1 %)",
        DIELECTRIC,
        "19.1 %",
    ),
    ("end within 3.3 % and 9.4 % of σ_t", DIELECTRIC, "3.3 %"),
    ("end within 3.3 % and 9.4 % of σ_t", DIELECTRIC, "9.4"),
    ("0.0024 of α", DIELECTRIC, "0.0024"),
    (
        "8.7 %, 4 of 9 `failed`, σ_t determined only",
        DIELECTRIC,
        "8.7 %",
    ),
    // A g per channel.
    ("recovers each within 0.024", FREE, "0.024"),
    ("leaves σ_t 33–92 % off", FREE, "33–92 %"),
    ("8.7 %, 4 of 9 `failed`", DIELECTRIC, "4 of 9"),
    ("(R and G, within 1.4 %)", DIELECTRIC, "1.4 %"),
    // Guided walks against the classical walk.
    ("variance × time 0.82–1.17×", WALKS, "0.82–1.17"),
    // The planar dipole baseline.
    ("6–41 % too dark front-lit", DIPOLE, "6–41 %"),
    ("58–86 % back-lit", DIPOLE, "58–86 %"),
    // The tracer against Mitsuba 3.
    ("means within 0.05–0.2 %", AGREEMENT, "0.05–0.2 %"),
    ("(0.86–0.92× its time at 64²)", TRACER_SPEED, "0.86–0.92×"),
    // The learned renderer against the tracer on coloured media.
    ("2.2–7.6× less pixel variance in G and B", NOISE, "2.2–7.6×"),
    ("0.56–1.13× in R", NOISE, "0.56–1.13×"),
    ("would give at most 2.2–2.4×", NOISE, "2.2–2.4×"),
    ("23–202× less noisy per second", NOISE, "23–202×"),
    ("1.4–7× noisier in R", NOISE, "1.4–7×"),
    // A light of unknown strength.
    (
        "1.629 [1.290, 2.058] against a truth of 2",
        FREE,
        "1.629 [1.290, 2.058]",
    ),
];

const FREE: &str = "### Recovering g and the light's strength (`--free`)";

const RECOVERY_SPEED: &str = "### Recovery speed at the paper's workload";
const TIME_TO_ACCURACY: &str = "### Time to an accurate answer";
const ACCURACY: &str = "### Accuracy on the paper's experiment (`experiment accuracy`)";
const ROBUSTNESS: &str = "### Robustness on data we did not tune on (experiment robustness)";
const VOLUMETRIC: &str = "### The volumetric baseline on the suite (`--model volpath`)";
const DIELECTRIC: &str =
    "### Dielectric boundaries and forward scattering (`--suite dielectric`, reduced scale)";
const LEARNED_GN: &str = "### The learned model over g, η and roughness";
const DIPOLE: &str = "### The planar dipole baseline on the suite (`--model dipole`)";
const AGREEMENT: &str = "### Agreement with Mitsuba 3 (`validate-mitsuba`)";
const TRACER_SPEED: &str = "### Speed against Mitsuba 3";
const WALKS: &str = "### Guided walks (`translucent-dev walks`)";
const NOISE: &str = "## Learned BSSRDF on coloured media: pixel sampling (`translucent-dev noise`)";
const PYTHON: &str = "## Python";

fn read(name: &str) -> String {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(name);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The level of a Markdown heading line (`## x` → 2), or `None` for any other line.
fn heading_level(line: &str) -> Option<usize> {
    let hashes = line.len() - line.trim_start_matches('#').len();
    (hashes > 0 && line[hashes..].starts_with(' ')).then_some(hashes)
}

/// The text of `doc` from the line `heading` to the next heading of the same or a higher level
/// (lines inside fenced code blocks are not headings).
fn section<'a>(doc: &'a str, heading: &str) -> Option<&'a str> {
    let level = heading_level(heading).expect("a heading starts with #");
    let mut start = None;
    let mut in_code = false;
    let mut offset = 0;
    for line in doc.split_inclusive('\n') {
        let text = line.trim_end();
        if text.starts_with("```") {
            in_code = !in_code;
        } else if !in_code {
            match start {
                None if text == heading => start = Some(offset),
                Some(s) if heading_level(text).is_some_and(|l| l <= level) => {
                    return Some(&doc[s..offset]);
                }
                _ => {}
            }
        }
        offset += line.len();
    }
    start.map(|s| &doc[s..])
}

/// Whether `text` contains `number` as a whole number: not inside a longer one ("4.17" is not in
/// "4.174", "2 of 48" is not in "12 of 48").
fn contains_number(text: &str, number: &str) -> bool {
    let digit_before = |i: usize| {
        text[..i]
            .chars()
            .next_back()
            .is_some_and(|c| c.is_ascii_digit() || c == '.')
    };
    let digit_after = |i: usize| {
        let mut rest = text[i..].chars();
        match rest.next() {
            Some(c) if c.is_ascii_digit() => true,
            Some('.') | Some(',') => rest.next().is_some_and(|c| c.is_ascii_digit()),
            _ => false,
        }
    };
    text.match_indices(number)
        .any(|(i, m)| !digit_before(i) && !digit_after(i + m.len()))
}

#[test]
fn readme_results_quote_benchmarks() {
    let readme = read("README.md");
    let benchmarks = read("BENCHMARKS.md");
    let results = section(&readme, "## Results").expect("README.md has a \"## Results\" section");
    let mut failures = Vec::new();
    for &(quote, heading, number) in FIGURES {
        assert!(
            contains_number(quote, number),
            "the table of this test is wrong: {number:?} is not in {quote:?}"
        );
        if !results.contains(quote) {
            failures.push(format!(
                "{number}: README.md's Results section no longer says {quote:?}"
            ));
        }
        match section(&benchmarks, heading) {
            None => failures.push(format!(
                "{number}: BENCHMARKS.md has no section {heading:?}"
            )),
            Some(text) if !contains_number(text, number) => failures.push(format!(
                "{number}: not in BENCHMARKS.md's section {heading:?} (README: {quote:?})"
            )),
            Some(_) => {}
        }
    }
    assert!(
        failures.is_empty(),
        "README.md and BENCHMARKS.md disagree:\n  {}",
        failures.join("\n  ")
    );
}

#[test]
fn sections_and_numbers_are_found_as_meant() {
    let doc = "# A\n\n## B\ntext 4.174 and 12 of 48\n```\n# not a heading\n```\n### C\n\
               in C 1.4×\n## D\nin D\n";
    let b = section(doc, "## B").unwrap();
    assert!(b.contains("in C") && !b.contains("in D"));
    assert_eq!(section(doc, "### C").unwrap(), "### C\nin C 1.4×\n");
    assert!(section(doc, "## E").is_none());
    assert!(!contains_number(b, "4.17"));
    assert!(contains_number(b, "4.174"));
    assert!(!contains_number(b, "2 of 48"));
    assert!(contains_number(b, "12 of 48"));
    assert!(contains_number("(1.41)", "1.41"));
    assert!(contains_number("at 1.41.", "1.41"));
    assert!(contains_number("in C 1.4×", "1.4×"));
}
