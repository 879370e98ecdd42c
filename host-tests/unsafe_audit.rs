//! Where `unsafe` may be and what it must say, checked on the source (`src/`):
//!
//! * every `unsafe` (block, `unsafe fn`, `unsafe impl`, `unsafe extern` item) carries a
//!   `// SAFETY:` note: on its line or in the comment just above the statement (at
//!   most [`MAX_CODE_LINES_BETWEEN`] lines of the same statement or of attributes
//!   between), and no other `unsafe` between note and use, so each has its own. An
//!   `unsafe fn` may instead document its callers' contract under `# Safety` (the
//!   convention of `clippy::missing_safety_doc`);
//! * `unsafe` and `allow(unsafe_code)` appear only under `src/board/` and in the
//!   [`EXCEPTIONS`], and every such allowance says why on its line (Cargo.toml's
//!   `[lints.rust]` denies `unsafe_code` for the package; checked too);
//! * the board layer depends on the hardware seam, never on the controller.
//!
//! Comments, string and character literals are told from code by a small lexer, so the
//! word `unsafe` in a comment or a string counts for nothing.

use std::path::{Path, PathBuf};

/// Modules outside `src/board/` that may hold `unsafe`, and why.
const EXCEPTIONS: &[(&str, &str)] = &[
    (
        "src/mem.rs",
        "memcpy/memset/memcmp and __aeabi_mem* for the target: raw-pointer routines with \
         C's contracts, exported under the names the compiler calls (`no_mangle`)",
    ),
    (
        "src/softfloat.rs",
        "the __aeabi_d* f64 routines for the target, exported under the names the \
         compiler calls (`no_mangle`, which `unsafe_code` counts); no `unsafe` block",
    ),
];

/// Lines of code (the rest of the statement, attributes) allowed between a note and
/// its `unsafe`.
const MAX_CODE_LINES_BETWEEN: usize = 3;
/// How far above an `unsafe` its note may start (lines, comments included).
const MAX_LINES_ABOVE: usize = 16;

/// One source line split into its code (literals blanked) and its comment text.
#[derive(Debug, Default, Clone)]
struct Line {
    code: String,
    comment: String,
}

/// Splits Rust source into lines of code and comment: line and (nested) block comments,
/// string, byte-string, raw-string and character literals; lifetimes stay code.
fn lex(src: &str) -> Vec<Line> {
    let chars: Vec<char> = src.chars().collect();
    let mut lines = vec![Line::default()];
    let mut i = 0;
    let push_code = |lines: &mut Vec<Line>, c: char| {
        if c == '\n' {
            lines.push(Line::default());
        } else if let Some(l) = lines.last_mut() {
            l.code.push(c);
        }
    };
    let push_comment = |lines: &mut Vec<Line>, c: char| {
        if c == '\n' {
            lines.push(Line::default());
        } else if let Some(l) = lines.last_mut() {
            l.comment.push(c);
        }
    };
    let at = |i: usize| chars.get(i).copied().unwrap_or('\0');
    let ident = |c: char| c.is_alphanumeric() || c == '_';
    while i < chars.len() {
        let c = chars[i];
        if c == '/' && at(i + 1) == '/' {
            while i < chars.len() && chars[i] != '\n' {
                push_comment(&mut lines, chars[i]);
                i += 1;
            }
        } else if c == '/' && at(i + 1) == '*' {
            let mut depth = 0;
            while i < chars.len() {
                if chars[i] == '/' && at(i + 1) == '*' {
                    depth += 1;
                    push_comment(&mut lines, '/');
                    push_comment(&mut lines, '*');
                    i += 2;
                } else if chars[i] == '*' && at(i + 1) == '/' {
                    depth -= 1;
                    push_comment(&mut lines, '*');
                    push_comment(&mut lines, '/');
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    push_comment(&mut lines, chars[i]);
                    i += 1;
                }
            }
        } else if c == 'r'
            && (at(i + 1) == '"' || at(i + 1) == '#')
            && !(i > 0 && ident(chars[i - 1]) && chars[i - 1] != 'b')
        {
            // Raw string r"..." / r#"..."# (also after b).
            let mut j = i + 1;
            let mut hashes = 0;
            while at(j) == '#' {
                hashes += 1;
                j += 1;
            }
            if at(j) != '"' {
                push_code(&mut lines, c);
                i += 1;
                continue;
            }
            push_code(&mut lines, '"');
            i = j + 1;
            while i < chars.len() {
                if chars[i] == '"' && (1..=hashes).all(|k| at(i + k) == '#') {
                    i += 1 + hashes;
                    break;
                }
                push_code(&mut lines, if chars[i] == '\n' { '\n' } else { ' ' });
                i += 1;
            }
            push_code(&mut lines, '"');
        } else if c == '"' {
            push_code(&mut lines, '"');
            i += 1;
            while i < chars.len() && chars[i] != '"' {
                if chars[i] == '\\' {
                    push_code(&mut lines, ' ');
                    i += 1;
                }
                if i < chars.len() {
                    push_code(&mut lines, if chars[i] == '\n' { '\n' } else { ' ' });
                    i += 1;
                }
            }
            push_code(&mut lines, '"');
            i += 1;
        } else if c == '\'' {
            // A character literal ('x', '\n', '\u{..}', '\'') or a lifetime ('a).
            if at(i + 1) == '\\' {
                let mut j = i + 2;
                while j < chars.len() && chars[j] != '\'' {
                    j += 1;
                }
                // '\'' : the escaped quote is the character.
                if j == i + 2 {
                    j = i + 3;
                }
                push_code(&mut lines, '\'');
                push_code(&mut lines, '\'');
                i = j + 1;
            } else if at(i + 2) == '\'' {
                push_code(&mut lines, '\'');
                push_code(&mut lines, '\'');
                i += 3;
            } else {
                push_code(&mut lines, c);
                i += 1;
            }
        } else {
            push_code(&mut lines, c);
            i += 1;
        }
    }
    lines
}

/// Whether `code` has the word `word` (not part of a longer identifier).
fn has_word(code: &str, word: &str) -> bool {
    code.split(|c: char| !(c.is_alphanumeric() || c == '_'))
        .any(|w| w == word)
}

/// An `unsafe fn` (or `unsafe extern "..." fn`) declaration on this line of code.
fn declares_unsafe_fn(code: &str) -> bool {
    let words: Vec<&str> = code
        .split(|c: char| !(c.is_alphanumeric() || c == '_'))
        .filter(|w| !w.is_empty())
        .collect();
    // An ABI string is blanked by the lexer: `unsafe extern "C" fn` reads `unsafe extern fn`.
    words.windows(2).any(|w| w == ["unsafe", "fn"])
        || words.windows(3).any(|w| w == ["unsafe", "extern", "fn"])
}

/// The 1-based lines of `src` whose `unsafe` has no note, and the number of lines with
/// an `unsafe`.
fn unsafe_without_note(src: &str) -> (Vec<usize>, usize) {
    let lines = lex(src);
    let mut missing = Vec::new();
    let mut sites = 0;
    for (i, line) in lines.iter().enumerate() {
        if !has_word(&line.code, "unsafe") {
            continue;
        }
        sites += 1;
        let is_fn = declares_unsafe_fn(&line.code);
        let noted =
            |l: &Line| l.comment.contains("SAFETY:") || (is_fn && l.comment.contains("# Safety"));
        let mut ok = noted(line);
        let mut code_lines = 0;
        for above in lines[i.saturating_sub(MAX_LINES_ABOVE)..i].iter().rev() {
            if ok {
                break;
            }
            if has_word(&above.code, "unsafe") {
                break; // that note, if any, is the other `unsafe`'s
            }
            if noted(above) {
                ok = true;
                break;
            }
            if above.code.trim().is_empty() && above.comment.trim().is_empty() {
                break; // a blank line ends the statement's comment block
            }
            if !above.code.trim().is_empty() {
                code_lines += 1;
                if code_lines > MAX_CODE_LINES_BETWEEN {
                    break;
                }
            }
        }
        if !ok {
            missing.push(i + 1);
        }
    }
    (missing, sites)
}

/// The workspace's root (this test belongs to the root package m2ctl).
fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every `.rs` file under `src/`, `calib/src/` and `ground/src/`, relative to the root.
fn sources() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let mut entries: Vec<_> = std::fs::read_dir(dir)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
            .filter_map(Result::ok)
            .map(|e| e.path())
            .collect();
        entries.sort();
        for p in entries {
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    let mut out = Vec::new();
    // The flight crate and the workspace's ground crates (which may hold no `unsafe`).
    for dir in ["src", "calib/src", "ground/src"] {
        walk(&root().join(dir), &mut out);
    }
    out.into_iter()
        .map(|p| p.strip_prefix(root()).map(Path::to_path_buf).unwrap_or(p))
        .collect()
}

fn read(rel: &Path) -> String {
    std::fs::read_to_string(root().join(rel)).unwrap_or_else(|e| panic!("{}: {e}", rel.display()))
}

fn unix(p: &Path) -> String {
    p.to_string_lossy().replace('\\', "/")
}

#[test]
fn every_unsafe_in_src_has_a_safety_note() {
    let mut missing = Vec::new();
    let (mut sites, mut files) = (0, 0);
    for rel in sources() {
        let (m, n) = unsafe_without_note(&read(&rel));
        if n > 0 {
            files += 1;
            sites += n;
        }
        missing.extend(m.into_iter().map(|l| format!("{}:{l}", unix(&rel))));
    }
    eprintln!("lines with `unsafe` in src/: {sites}, in {files} files");
    assert!(
        missing.is_empty(),
        "`unsafe` without a `// SAFETY:` note just above (or `# Safety` for an unsafe fn): \
         {missing:#?}"
    );
    assert!(
        sites > 0,
        "the scan found no `unsafe` at all: is it reading src/?"
    );
}

#[test]
fn unsafe_only_in_the_board_layer_and_the_documented_exceptions() {
    let mut outside = Vec::new();
    let mut silent = Vec::new();
    for rel in sources() {
        let path = unix(&rel);
        let lines = lex(&read(&rel));
        let uses = lines.iter().any(|l| has_word(&l.code, "unsafe"));
        let allows: Vec<&Line> = lines
            .iter()
            .filter(|l| l.code.contains("allow(unsafe_code)"))
            .collect();
        let permitted =
            path.starts_with("src/board/") || EXCEPTIONS.iter().any(|(p, _)| *p == path);
        if (uses || !allows.is_empty()) && !permitted {
            outside.push(path.clone());
        }
        if allows
            .iter()
            .any(|l| l.comment.trim_start_matches('/').trim().is_empty())
        {
            silent.push(path);
        }
    }
    assert!(
        outside.is_empty(),
        "`unsafe` or allow(unsafe_code) outside src/board/ and the documented exceptions \
         (add it to EXCEPTIONS with its reason only if it cannot be in the board layer): \
         {outside:?}"
    );
    assert!(
        silent.is_empty(),
        "allow(unsafe_code) without its reason on the same line: {silent:?}"
    );
    for (path, why) in EXCEPTIONS {
        let src = read(Path::new(path));
        assert!(
            lex(&src)
                .iter()
                .any(|l| l.code.contains("allow(unsafe_code)")),
            "{path} is listed as an exception ({why}) but allows no unsafe_code: drop it"
        );
    }
    let manifest = read(Path::new("Cargo.toml"));
    let rust_lints = manifest
        .split("[workspace.lints.rust]")
        .nth(1)
        .and_then(|s| s.split("\n[").next())
        .unwrap_or("");
    assert!(
        rust_lints
            .lines()
            .any(|l| l.trim() == "unsafe_code = \"deny\""),
        "Cargo.toml's [workspace.lints.rust] must deny unsafe_code for the workspace"
    );
    // ... and every member takes the workspace's lints.
    for member in ["Cargo.toml", "calib/Cargo.toml", "ground/Cargo.toml"] {
        let m = read(Path::new(member));
        assert!(
            m.contains("[lints]\nworkspace = true"),
            "{member} must take the workspace's lints (`[lints] workspace = true`)"
        );
    }
}

#[test]
fn the_board_layer_does_not_depend_on_the_controller() {
    let offending: Vec<String> = sources()
        .into_iter()
        .filter(|rel| unix(rel).starts_with("src/board/"))
        .flat_map(|rel| {
            let path = unix(&rel);
            lex(&read(&rel))
                .into_iter()
                .enumerate()
                .filter(|(_, l)| {
                    l.code.contains("crate::controller") || l.code.contains("controller::")
                })
                .map(move |(i, _)| format!("{path}:{}", i + 1))
                .collect::<Vec<_>>()
        })
        .collect();
    assert!(
        offending.is_empty(),
        "the board layer names the controller (it depends on `crate::hw` only): {offending:?}"
    );
}

// The checker itself.

#[test]
fn the_lexer_ignores_unsafe_in_comments_and_literals() {
    let src = r##"
// unsafe in a comment
/* unsafe /* nested */ unsafe */
let s = "unsafe \" unsafe";
let r = r#"unsafe "quoted" unsafe"#;
let c = '"'; let d = '\''; fn f<'a>(x: &'a u8) {}
let unsafe_code = 1;
"##;
    let (missing, sites) = unsafe_without_note(src);
    assert_eq!((missing, sites), (vec![], 0));
}

#[test]
fn the_checker_finds_a_missing_note_and_accepts_each_note_form() {
    let src = "\
fn a() {
    // SAFETY: a's note.
    unsafe { x() };
    unsafe { y() };
}

// SAFETY: a note for something else.

fn b() { unsafe { z() } }
fn c() {
    let v = thing
        .chain()
        // SAFETY: inside the chain.
        .map(|w| unsafe { w.bits(0) });
    let t = unsafe { q() }; // SAFETY: on its line.
}
/// Does things.
///
/// # Safety
/// The caller's contract.
#[no_mangle]
pub unsafe extern \"C\" fn d() {}
/// # Safety
/// Not enough for a block.
fn e() { unsafe { w() } }
";
    let (missing, sites) = unsafe_without_note(src);
    assert_eq!(sites, 7);
    assert_eq!(missing, vec![4, 9, 25]);
}
