//! The text format of `quadtex query` (documented in the README).

use quadtex_core::Fragment;

/// Parses one query line: `x0 z0 x1 z1`, whitespace-separated decimal
/// numbers. Blank lines and lines starting with `#` give `Ok(None)`. The
/// error message names the field at fault; the caller adds the line number.
pub fn parse_query_line(line: &str) -> Result<Option<Fragment>, String> {
    let line = line.trim();
    if line.is_empty() || line.starts_with('#') {
        return Ok(None);
    }
    let mut v = [0f64; 4];
    let mut fields = line.split_whitespace();
    for (slot, name) in v.iter_mut().zip(["x0", "z0", "x1", "z1"]) {
        let text = fields
            .next()
            .ok_or_else(|| format!("expected 4 numbers `x0 z0 x1 z1`, missing {name}"))?;
        *slot = text
            .parse()
            .map_err(|_| format!("{name}: `{text}` is not a number"))?;
    }
    if fields.next().is_some() {
        return Err(format!(
            "expected 4 numbers `x0 z0 x1 z1`, found {}",
            line.split_whitespace().count()
        ));
    }
    Fragment::new(v[0], v[1], v[2], v[3])
        .map(Some)
        .map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_or_names_the_problem() {
        assert!(parse_query_line("  # comment").unwrap().is_none());
        assert!(parse_query_line("").unwrap().is_none());
        let f = parse_query_line("0 0.25\t1 0.5").unwrap().unwrap();
        assert_eq!((f.x0(), f.z0(), f.x1(), f.z1()), (0.0, 0.25, 1.0, 0.5));
        for (line, needle) in [
            ("0 0 1", "missing z1"),
            ("0 0 1 1 5", "found 5"),
            ("0 0 x 1", "x1: `x` is not a number"),
            ("0 NaN 1 1", "z0 is not finite"),
            ("0 0 inf 1", "x1 is not finite"),
            ("1 0 0 1", "reversed bounds on x"),
        ] {
            let e = parse_query_line(line).unwrap_err();
            assert!(e.contains(needle), "{line}: {e}");
        }
    }
}
