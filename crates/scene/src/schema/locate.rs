//! Blaming the right key inside internally tagged tables (`[plant] kind = "pneumatic"`, events, force pieces).
//!
//! serde reads such a table whole before it knows the variant, so its errors stop at the table (`plant`)
//! even when one field is wrong (`substeps = 10.5`). The message still names the field (unknown field) or
//! shows the offending value (invalid type or value); this finds the one key it belongs to.

use toml::de::{DeTable, DeValue};

/// The key path `path` refined to the field of the tagged table at `path` that `message` is about, or
/// `path` unchanged when the message does not single one out.
pub fn blame_inside_tagged(text: &str, path: &str, message: &str) -> String {
    let Some(table) = table_at(text, path) else {
        return path.to_string();
    };
    let join = |k: &str| {
        if path.is_empty() {
            k.to_string()
        } else {
            format!("{path}.{k}")
        }
    };
    if let Some(field) = backticked(message, "unknown field `") {
        return join(field);
    }
    let shown = ["invalid type: ", "invalid value: "]
        .iter()
        .find_map(|p| message.strip_prefix(p))
        .and_then(|rest| {
            backticked(rest, "`").or_else(|| {
                // strings are shown quoted: string "abc", expected ...
                let r = rest.strip_prefix("string \"")?;
                Some(&r[..r.find('"')?])
            })
        });
    let Some(shown) = shown else {
        return path.to_string();
    };
    let matches: Vec<&str> = table
        .iter()
        .filter(|(k, _)| k.get_ref() != "kind")
        .filter(|(_, v)| same_value(text, v.span(), v.get_ref(), shown))
        .map(|(k, _)| k.get_ref().as_ref())
        .collect();
    match matches.as_slice() {
        [one] => join(one),
        _ => path.to_string(),
    }
}

fn backticked<'a>(message: &'a str, prefix: &str) -> Option<&'a str> {
    let start = message.find(prefix)? + prefix.len();
    let end = message[start..].find('`')?;
    Some(&message[start..start + end])
}

fn same_value(text: &str, span: std::ops::Range<usize>, v: &DeValue<'_>, shown: &str) -> bool {
    match v {
        DeValue::String(s) => s.as_ref() == shown,
        DeValue::Boolean(b) => b.to_string() == shown,
        DeValue::Integer(_) | DeValue::Float(_) => {
            let raw = text.get(span).unwrap_or("").trim().replace('_', "");
            match (raw.parse::<f64>(), shown.parse::<f64>()) {
                (Ok(a), Ok(b)) => a == b || (a.is_nan() && b.is_nan()),
                _ => raw == shown,
            }
        }
        _ => false,
    }
}

/// The table at a dotted key path (with `[i]` indices), if the text parses and one is there.
fn table_at<'a>(text: &'a str, path: &str) -> Option<DeTable<'a>> {
    let root = DeTable::parse(text).ok()?.into_inner();
    let mut cur = DeValue::Table(root);
    for part in path.split('.').filter(|p| !p.is_empty()) {
        let (key, idx) = match part.find('[') {
            Some(i) => (&part[..i], Some(&part[i..])),
            None => (part, None),
        };
        if !key.is_empty() {
            let DeValue::Table(t) = cur else { return None };
            cur = t.get(key)?.get_ref().clone();
        }
        let mut rest = idx.unwrap_or("");
        while let Some(r) = rest.strip_prefix('[') {
            let end = r.find(']')?;
            let i: usize = r[..end].parse().ok()?;
            let DeValue::Array(a) = cur else { return None };
            cur = a.get(i)?.get_ref().clone();
            rest = &r[end + 1..];
        }
    }
    match cur {
        DeValue::Table(t) => Some(t),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::blame_inside_tagged;

    const DOC: &str = "[plant]\nkind = \"pneumatic\"\nactuator = \"a.toml\"\nsubsteps = 10.5\n\n[[events]]\nkind = \"alpha\"\nt_s = 1.0\nalpha_dg = 3.0\n";

    #[test]
    fn an_invalid_type_is_blamed_on_the_field_that_holds_the_value() {
        let p = blame_inside_tagged(
            DOC,
            "plant",
            "invalid type: floating point `10.5`, expected u32",
        );
        assert_eq!(p, "plant.substeps");
    }

    #[test]
    fn an_unknown_field_is_named() {
        let p = blame_inside_tagged(
            DOC,
            "events[0]",
            "unknown field `alpha_dg`, expected `t_s` or `alpha_deg`",
        );
        assert_eq!(p, "events[0].alpha_dg");
    }

    #[test]
    fn an_ambiguous_message_keeps_the_table() {
        assert_eq!(
            blame_inside_tagged(DOC, "plant", "missing field `x`"),
            "plant"
        );
    }
}
