//! The user's words (issue 28): no help text of any command speaks the patents' letters or the
//! statistics' shorthand a shop does not use. The patents are named only in docs/glossary.md.

mod support;

use support::run;

/// What a user must not meet: a patent's letter (`seed A`, `seed-c`), its embodiments, and
/// shorthand (`1se`, `rolling origin`, `switch rule`).
fn foreign_words(text: &str) -> Vec<String> {
    let lower = text.to_lowercase();
    let mut found = Vec::new();
    for (i, _) in lower.match_indices("seed") {
        let after: String = lower[i + 4..].chars().take(4).collect();
        let letter = |s: &str| {
            s.chars().next().is_some_and(|c| ('a'..='d').contains(&c))
                && !s[1..].starts_with(|c: char| c.is_alphanumeric())
        };
        let rest = after.trim_start_matches(['s', '\'', '’']);
        if let Some(r) = rest.strip_prefix([' ', '-']) {
            if letter(r) {
                found.push(format!("seed{after}"));
            }
        }
    }
    for w in ["embodiment", "1se", "rolling origin", "switch rule"] {
        if lower.contains(w) {
            found.push(w.to_string());
        }
    }
    found
}

/// The subcommands listed under `Commands:` of a help text.
fn commands(help: &str) -> Vec<String> {
    help.lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        // A command's line is indented by two spaces; a wrapped description by more.
        .filter(|l| !l.starts_with("   "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(String::from)
        .collect()
}

#[test]
fn the_words_are_caught() {
    assert_eq!(foreign_words("the model (seed A)"), vec!["seed a)"]);
    assert_eq!(foreign_words("family seed-c, or"), vec!["seed-c, "]);
    assert_eq!(foreign_words("seed A/C's families").len(), 1);
    assert_eq!(foreign_words("rule 1se"), vec!["1se"]);
    assert!(foreign_words("Seed of the random draws; the same seed gives").is_empty());
    assert!(foreign_words("seeds differ; seed 7").is_empty());
}

#[test]
fn no_help_text_speaks_the_patents_letters() {
    let (ok, top, err) = run(&["--help"]);
    assert!(ok, "{err}");
    let mut pages = vec![(String::from("truepos"), top.clone())];
    let mut queue: Vec<Vec<String>> = commands(&top).into_iter().map(|c| vec![c]).collect();
    while let Some(path) = queue.pop() {
        let mut args: Vec<&str> = path.iter().map(String::as_str).collect();
        args.push("--help");
        let (ok, text, err) = run(&args);
        assert!(ok, "truepos {}: {err}", args.join(" "));
        for sub in commands(&text) {
            let mut p = path.clone();
            p.push(sub);
            queue.push(p);
        }
        pages.push((format!("truepos {}", path.join(" ")), text));
    }
    assert!(pages.len() > 10, "{} help pages", pages.len());
    let bad: Vec<String> = pages
        .iter()
        .filter_map(|(name, text)| {
            let f = foreign_words(text);
            (!f.is_empty()).then(|| format!("{name}: {f:?}"))
        })
        .collect();
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}
