//! No input panics the compiler: mutated canonical scenes (proptest), every
//! truncation of every example, and pathological inputs.

use crate::{cso_files, root};
use cso::lang::{compile, diag, CheckOptions};
use proptest::prelude::*;

fn examples() -> Vec<String> {
    cso_files(&root().join("examples"))
        .iter()
        .map(|p| std::fs::read_to_string(p).expect("readable"))
        .collect()
}

/// Compiles and renders; rendering runs too because it slices the source by spans.
fn run(src: &str) {
    for limit in [Some(16u64 << 30), None] {
        let opts = CheckOptions {
            overrides: Vec::new(),
            memory_limit: limit,
            base_dir: None,
            mesh_cache: None,
        };
        if let Err(d) = compile(src, &opts) {
            assert!(!d.is_empty());
            let _ = diag::render(&d, "fuzz.cso", src);
        }
        if limit.is_some() && src.len() > 2000 {
            // The no-limit path is only cheap for small meshes; once is enough.
            break;
        }
    }
}

/// Tokens that make interesting mistakes when dropped anywhere.
const TOKENS: &[&str] = &[
    "{",
    "}",
    "(",
    ")",
    "[",
    "]",
    ",",
    "=",
    "..",
    " x ",
    "^",
    "-",
    "1e400",
    "0",
    " mm",
    " GPa",
    "\"",
    "#",
    "\n",
    "a[99]",
    "bezier(",
    "sqrt(-1)",
    "1/0",
    "&&",
    "!",
    ".",
    "punch",
    "z",
    "uz",
    "999999999 x 999999999",
    "let",
    "body",
    "design q[3] {",
    "0 .. 0",
    "nu = 0.5",
    "-1",
    "é",
    "\t",
    "ln(0)",
    "x",
    "y",
    "initial(",
    "contact_force(",
    "2^2^2^2",
    "pi",
    ";",
    ":",
];

#[derive(Debug, Clone)]
enum Edit {
    Insert(usize, usize),
    Delete(usize, usize),
    Replace(usize, usize, usize),
    DuplicateLine(usize),
    Text(usize, String),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (any::<usize>(), 0..TOKENS.len()).prop_map(|(p, t)| Edit::Insert(p, t)),
        (any::<usize>(), 1..12usize).prop_map(|(p, n)| Edit::Delete(p, n)),
        (any::<usize>(), 1..6usize, 0..TOKENS.len()).prop_map(|(p, n, t)| Edit::Replace(p, n, t)),
        any::<usize>().prop_map(Edit::DuplicateLine),
        (any::<usize>(), "\\PC{0,6}").prop_map(|(p, s)| Edit::Text(p, s)),
    ]
}

fn boundary(s: &str, p: usize) -> usize {
    let mut p = p % (s.len() + 1);
    while !s.is_char_boundary(p) {
        p -= 1;
    }
    p
}

fn apply(src: &mut String, e: &Edit) {
    match e {
        Edit::Insert(p, t) => {
            let p = boundary(src, *p);
            src.insert_str(p, TOKENS[*t]);
        }
        Edit::Delete(p, n) | Edit::Replace(p, n, _) => {
            let a = boundary(src, *p);
            let b = boundary(src, (a + n).min(src.len()));
            let b = b.max(a);
            let with = if let Edit::Replace(_, _, t) = e {
                TOKENS[*t]
            } else {
                ""
            };
            src.replace_range(a..b, with);
        }
        Edit::DuplicateLine(p) => {
            let lines: Vec<&str> = src.lines().collect();
            if !lines.is_empty() {
                let i = p % lines.len();
                let line = lines[i].to_string();
                let at = boundary(src, src.find(lines[i]).unwrap_or(0));
                src.insert_str(at, &format!("{line}\n"));
            }
        }
        Edit::Text(p, s) => {
            let p = boundary(src, *p);
            src.insert_str(p, s);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 384, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn mutated_examples_never_panic(which in 0..6usize, edits in prop::collection::vec(edit(), 1..6)) {
        let all = examples();
        let mut src = all[which % all.len()].clone();
        for e in &edits {
            apply(&mut src, e);
        }
        run(&src);
    }

    #[test]
    fn arbitrary_text_never_panics(src in "\\PC{0,200}") {
        run(&src);
    }
}

#[test]
fn every_truncation_of_every_example_is_handled() {
    for src in examples() {
        let mut cut = 0;
        while cut < src.len() {
            run(&src[..cut]);
            cut += 3;
        }
    }
}

#[test]
fn pathological_inputs_are_refused_without_crashing() {
    let deep_parens = format!("let a = {}1{}", "(".repeat(5000), ")".repeat(5000));
    let long_chain = format!("let a = 1{}", "+1".repeat(100_000));
    let power_tower = format!("let a = 2{}", "^2".repeat(20_000));
    let unary = format!("let a = {}1", "-".repeat(100_000));
    let many_items = "let a = 1\n".repeat(20_000);
    let huge_number = format!("let a = {}", "9".repeat(400));
    let nested_lists = format!(
        "design a[2] {{ init = {}0{} }}",
        "[".repeat(3000),
        "]".repeat(3000)
    );
    // Right at the limits: accepted, and nothing overflows the stack of a test thread.
    let at_depth = format!("let a = {}1{}", "(-".repeat(31), ")".repeat(31));
    let at_chain = format!("let a = 1{}", "+1".repeat(255));
    let at_tower = format!("let a = 1{}", "^1".repeat(255));
    let let_chain: String = (0..63)
        .map(|i| format!("let c{i} = c{} + 1\n", i + 1))
        .collect::<String>()
        + "let c63 = 0\n";
    for src in [&at_depth, &at_chain, &at_tower, &let_chain] {
        let full = format!("scene s {{ dim = 2 }}\n{src}\n");
        assert!(
            compile(&full, &CheckOptions::default()).is_ok(),
            "{}",
            &src[..40]
        );
    }
    for src in [
        deep_parens,
        long_chain,
        power_tower,
        unary,
        many_items,
        huge_number,
        nested_lists,
    ] {
        let src = format!("scene s {{ dim = 2 }}\n{src}\n");
        run(&src);
    }
}
