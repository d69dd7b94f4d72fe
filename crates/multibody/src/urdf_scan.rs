//! A streaming pre-scan of URDF text, run before `urdf-rs` sees it:
//! - nesting depth is limited: urdf-rs' XML reader recurses per element, and 20,000 nested elements
//!   overflowed the stack (an abort, not an error);
//! - every numeric attribute URDF defines must hold the right count of numbers, so that an error names the
//!   file, the line and the element (urdf-rs says only `custom: invalid float literal`).
//!
//! quick-xml's reader is iterative and handles comments, CDATA, processing instructions and self-closing
//! tags; attribute values are unescaped before they are parsed.

use std::path::Path;

use quick_xml::Reader;
use quick_xml::events::{BytesStart, Event};

use crate::error::MultibodyError;

/// Deepest element nesting accepted. A URDF needs 5 levels (robot/link/collision/geometry/box); 64 leaves
/// room for extensions (`<gazebo>` blocks) and keeps urdf-rs' recursion far from the stack's end.
pub const MAX_DEPTH: usize = 64;

/// How the numbers of one attribute are checked.
#[derive(Clone, Copy)]
enum Numbers {
    /// `n` finite numbers.
    Finite(usize),
    /// One number; `inf` / `-inf` allowed (URDF limits: no limit), NaN not.
    MaybeInfinite,
}

/// The numeric attributes of `element` when its parent is `parent`, as URDF (1.0-1.2) defines them.
fn numeric_attributes(parent: &str, element: &str) -> &'static [(&'static str, Numbers)] {
    use Numbers::{Finite, MaybeInfinite};
    const ONE: Numbers = Finite(1);
    match (parent, element) {
        ("inertial", "mass") => &[("value", ONE)],
        ("inertial", "inertia") => &[
            ("ixx", ONE),
            ("ixy", ONE),
            ("ixz", ONE),
            ("iyy", ONE),
            ("iyz", ONE),
            ("izz", ONE),
        ],
        ("inertial" | "visual" | "collision" | "joint", "origin") => &[
            ("xyz", Finite(3)),
            ("rpy", Finite(3)),
            ("quat_xyzw", Finite(4)),
        ],
        ("joint", "axis") => &[("xyz", Finite(3))],
        ("joint", "limit") => &[
            ("lower", MaybeInfinite),
            ("upper", MaybeInfinite),
            ("effort", MaybeInfinite),
            ("velocity", MaybeInfinite),
            ("acceleration", MaybeInfinite),
            ("deceleration", MaybeInfinite),
            ("jerk", MaybeInfinite),
        ],
        ("joint", "dynamics") => &[("damping", ONE), ("friction", ONE)],
        ("joint", "mimic") => &[("multiplier", ONE), ("offset", ONE)],
        ("joint", "calibration") => &[("rising", ONE), ("falling", ONE)],
        ("joint", "safety_controller") => &[
            ("soft_lower_limit", ONE),
            ("soft_upper_limit", ONE),
            ("k_position", ONE),
            ("k_velocity", ONE),
        ],
        ("geometry", "box") => &[("size", Finite(3))],
        ("geometry", "cylinder" | "capsule") => &[("radius", ONE), ("length", ONE)],
        ("geometry", "sphere") => &[("radius", ONE)],
        ("geometry", "mesh") => &[("scale", Finite(3))],
        ("material", "color") => &[("rgba", Finite(4))],
        _ => &[],
    }
}

/// Why `value` is not what `kind` asks for, if it is not.
fn numbers_problem(value: &str, kind: Numbers) -> Option<String> {
    let parsed: Vec<Option<f64>> = value
        .split_whitespace()
        .map(|s| s.parse::<f64>().ok())
        .collect();
    let ok = match kind {
        Numbers::Finite(n) => {
            parsed.len() == n && parsed.iter().all(|v| v.is_some_and(f64::is_finite))
        }
        Numbers::MaybeInfinite => parsed.len() == 1 && parsed[0].is_some_and(|v| !v.is_nan()),
    };
    if ok {
        return None;
    }
    Some(match kind {
        Numbers::Finite(1) => format!("expected a finite number, got \"{value}\""),
        Numbers::Finite(n) => {
            format!("expected {n} finite numbers separated by spaces, got \"{value}\"")
        }
        Numbers::MaybeInfinite => {
            format!("expected a number (inf for no limit), got \"{value}\"")
        }
    })
}

/// The start tag as written, shortened for messages: `<mass value="heavy">`.
fn tag_text(e: &BytesStart<'_>) -> String {
    let raw = String::from_utf8_lossy(e);
    let raw = raw.trim().trim_end_matches('/').trim_end();
    let mut s: String = raw.chars().take(100).collect();
    if s.len() < raw.len() {
        s.push_str(" ...");
    }
    format!("<{s}>")
}

/// An open element: its name and, for links and joints, the name attribute (for messages).
struct Open {
    name: String,
    owner: Option<String>,
}

/// Checks URDF text: well-formed XML, nesting at most [`MAX_DEPTH`], numeric attributes that parse.
/// Errors name the file, the line and the element (and the link or joint it belongs to).
pub fn scan(file: &Path, text: &str) -> Result<(), MultibodyError> {
    let line_at = |offset: u64| pneuflex_files::line_col(text, offset as usize).line;
    let syntax = |offset: u64, reason: String| MultibodyError::Parse {
        file: file.to_path_buf(),
        reason: format!("line {}: {reason}", line_at(offset)),
    };
    let mut reader = Reader::from_str(text);
    let mut stack: Vec<Open> = Vec::new();
    loop {
        let start = reader.buffer_position();
        let event = reader
            .read_event()
            .map_err(|e| syntax(reader.error_position(), e.to_string()))?;
        let (e, empty) = match event {
            Event::Start(e) => (e, false),
            Event::Empty(e) => (e, true),
            Event::End(_) => {
                stack.pop();
                continue;
            }
            Event::Eof => break,
            _ => continue,
        };
        let name = String::from_utf8_lossy(e.local_name().as_ref()).into_owned();
        let line = line_at(start);
        let element_err = |reason: String, stack: &[Open]| MultibodyError::Element {
            file: file.to_path_buf(),
            line,
            element: tag_text(&e),
            reason: match stack.iter().rev().find_map(|o| o.owner.as_deref()) {
                Some(owner) => format!("{reason} (in {owner})"),
                None => reason,
            },
        };
        if stack.len() >= MAX_DEPTH {
            return Err(element_err(
                format!(
                    "elements nested deeper than {MAX_DEPTH} levels (a URDF needs 5); refused before parsing"
                ),
                &stack,
            ));
        }
        let parent = stack.last().map_or("", |o| o.name.as_str());
        let wanted = numeric_attributes(parent, &name);
        let mut owner = None;
        for a in e.attributes() {
            let a = a.map_err(|err| syntax(start, format!("{}: {err}", tag_text(&e))))?;
            let key = String::from_utf8_lossy(a.key.local_name().as_ref()).into_owned();
            let value = a
                .unescape_value()
                .map_err(|err| syntax(start, format!("{}: {key}: {err}", tag_text(&e))))?;
            if key == "name" && matches!(name.as_str(), "link" | "joint") && parent == "robot" {
                owner = Some(format!("{name} '{value}'"));
            }
            if let Some(&(_, kind)) = wanted.iter().find(|(k, _)| *k == key)
                && let Some(problem) = numbers_problem(&value, kind)
            {
                return Err(element_err(format!("{key}: {problem}"), &stack));
            }
        }
        if !empty {
            stack.push(Open { name, owner });
        }
    }
    if let Some(open) = stack.last() {
        return Err(MultibodyError::Parse {
            file: file.to_path_buf(),
            reason: format!("<{}> is not closed at the end of the file", open.name),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> String {
        scan(Path::new("t.urdf"), text).unwrap_err().to_string()
    }

    #[test]
    fn comments_cdata_pis_and_self_closing_tags_do_not_nest() {
        let ok = "<?xml version=\"1.0\"?>\n<!-- <a><b> -->\n<robot name=\"r\"><?pi <x>?>\
                  <link name=\"l\"><![CDATA[<c><d>]]><inertial><mass value=\"1\"/></inertial></link></robot>";
        scan(Path::new("t.urdf"), ok).unwrap();
        let deep = format!(
            "<robot>{}{}</robot>",
            "<a/>".repeat(1000),
            "<!--<b>-->".repeat(100)
        );
        scan(Path::new("t.urdf"), &deep).unwrap();
    }

    #[test]
    fn depth_limit_names_line_and_element() {
        let text = format!("<robot>\n{}", "<a>".repeat(MAX_DEPTH));
        let e = err(&text);
        assert!(
            e.starts_with("t.urdf:2: <a>: elements nested deeper than 64"),
            "{e}"
        );
    }

    #[test]
    fn vector_counts_and_limits() {
        let j = |attrs: &str| {
            format!(
                "<robot><joint name=\"j\" type=\"prismatic\">\n<limit {attrs}/></joint></robot>"
            )
        };
        scan(
            Path::new("t.urdf"),
            &j("lower=\"-inf\" upper=\"inf\" effort=\"1\" velocity=\"1\""),
        )
        .unwrap();
        let e = err(&j("lower=\"nan\""));
        assert!(e.contains("t.urdf:2: <limit lower=\"nan\">: lower:"), "{e}");
        assert!(e.contains("(in joint 'j')"), "{e}");
        let e =
            err("<robot><link name=\"l\"><visual><origin xyz=\"1 2\"/></visual></link></robot>");
        assert!(e.contains("xyz: expected 3 finite numbers"), "{e}");
        let e = err(
            "<robot><link name=\"l\"><visual><origin xyz=\"1 2 1e999\"/></visual></link></robot>",
        );
        assert!(e.contains("xyz: expected 3 finite numbers"), "{e}");
    }

    #[test]
    fn unclosed_and_mismatched_elements_are_parse_errors_with_lines() {
        let e = err("<robot>\n<link name=\"a\">\n</robot>");
        assert!(e.contains("line 3"), "{e}");
        let e = err("<robot>\n<link name=\"a\">");
        assert!(e.contains("<link> is not closed"), "{e}");
    }
}
