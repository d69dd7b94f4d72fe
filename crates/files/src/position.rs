//! Where a key is in a TOML file: line and column of a dotted key path such as `runs[1].inner.kp_per_m`,
//! so that validation errors (found after deserialising) point at the line as parse errors do.

use toml::de::{DeTable, DeValue};

/// A 1-based line and column in a text file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Position {
    /// Line, from 1.
    pub line: usize,
    /// Column (characters), from 1.
    pub column: usize,
}

impl std::fmt::Display for Position {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}", self.line, self.column)
    }
}

/// Line and column of byte `offset` in `text`.
pub fn line_col(text: &str, offset: usize) -> Position {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    Position {
        line,
        column: text[line_start..offset].chars().count() + 1,
    }
}

enum Segment<'a> {
    Key(&'a str),
    Index(usize),
}

/// Splits `a.b[2].c` into keys and indices; `None` for a path this syntax does not describe.
fn segments(path: &str) -> Option<Vec<Segment<'_>>> {
    let mut out = Vec::new();
    for part in path.split('.') {
        let (key, mut rest) = match part.find('[') {
            Some(i) => (&part[..i], &part[i..]),
            None => (part, ""),
        };
        if !key.is_empty() {
            out.push(Segment::Key(key));
        }
        while let Some(r) = rest.strip_prefix('[') {
            let end = r.find(']')?;
            out.push(Segment::Index(r[..end].parse().ok()?));
            rest = &r[end + 1..];
        }
        if !rest.is_empty() {
            return None;
        }
    }
    Some(out)
}

/// The position of the value at `path` in a TOML document; where the last key is absent, the position of
/// the deepest table that exists on the path (where the key would go). `None` when the text does not parse.
pub fn toml_key_position(text: &str, path: &str) -> Option<Position> {
    let root = DeTable::parse(text).ok()?;
    let segs = segments(path)?;
    let mut span = root.span();
    let mut here: Option<&DeValue<'_>> = None;
    let mut table: &DeTable<'_> = root.get_ref();
    let mut matched = 0;
    for seg in &segs {
        let next = match (seg, here) {
            (Segment::Key(k), None) => table.get(*k),
            (Segment::Key(k), Some(DeValue::Table(t))) => t.get(*k),
            (Segment::Index(i), Some(DeValue::Array(a))) => a.get(*i),
            _ => None,
        };
        let Some(v) = next else { break };
        matched += 1;
        span = v.span();
        here = Some(v.get_ref());
        if let DeValue::Table(t) = v.get_ref() {
            table = t;
        }
    }
    if matched == 0 && !segs.is_empty() {
        return None;
    }
    Some(line_col(text, span.start))
}

#[cfg(test)]
mod tests {
    use super::*;

    const DOC: &str = "name = \"x\"\nduration_s = 10.0\n\n[plant]\nkind = \"pneumatic\"\nsubsteps = 10.5\n\n[[runs]]\nname = \"a\"\n[runs.inner]\nkp_per_m = 7.0\n\n[[runs]]\nname = \"b\"\n[runs.inner]\nkp_per_m = -1.0\n";

    #[test]
    fn finds_nested_keys_and_array_entries() {
        assert_eq!(toml_key_position(DOC, "duration_s").unwrap().line, 2);
        assert_eq!(toml_key_position(DOC, "plant.substeps").unwrap().line, 6);
        assert_eq!(
            toml_key_position(DOC, "runs[1].inner.kp_per_m")
                .unwrap()
                .line,
            16
        );
        assert_eq!(
            toml_key_position(DOC, "runs[0].inner.kp_per_m").unwrap(),
            Position {
                line: 11,
                column: 12
            }
        );
    }

    #[test]
    fn a_missing_key_points_at_its_table() {
        let p = toml_key_position(DOC, "runs[1].inner.ki_per_m_s").unwrap();
        assert!(p.line >= 15 && p.line <= 16, "{p}");
    }

    #[test]
    fn line_col_counts_characters() {
        assert_eq!(line_col("a\nbé c", 6), Position { line: 2, column: 4 });
    }
}
