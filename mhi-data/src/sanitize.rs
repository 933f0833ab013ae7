//! Names taken from the file system (sequence names, file names) made safe to show: on a
//! terminal (no escape sequences, line breaks or direction marks) and in markdown (no markup).

/// Whether `c` could move the cursor, recolour the terminal, break a line or reorder text.
fn is_unsafe(c: char) -> bool {
    c.is_control()
        || matches!(c, '\u{200e}' | '\u{200f}' | '\u{061c}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}')
}

/// `s` with every control character (escape, newline, carriage return, C1 codes) and every
/// bidirectional mark replaced by `?`, so a name cannot rewrite what the terminal shows.
pub fn for_terminal(s: &str) -> String {
    s.chars()
        .map(|c| if is_unsafe(c) { '?' } else { c })
        .collect()
}

/// `s` for a markdown document (or a table cell): control characters and direction marks as in
/// [`for_terminal`], and every character that markdown or HTML would read as markup escaped
/// with a backslash (`<` and `>` as entities), so a name shows as text and nothing else.
pub fn for_markdown(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in for_terminal(s).chars() {
        match c {
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '&' => out.push_str("&amp;"),
            '\\' | '`' | '*' | '_' | '{' | '}' | '[' | ']' | '(' | ')' | '#' | '+' | '-' | '.'
            | '!' | '|' | '~' | '"' | '\'' => {
                out.push('\\');
                out.push(c);
            }
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_cannot_carry_escapes_or_markup() {
        assert_eq!(for_terminal("a\u{1b}[31mb\nc\u{202e}d"), "a?[31mb?c?d");
        assert_eq!(for_terminal("kitchen-01"), "kitchen-01");
        let md = for_markdown("<img src=x onerror=alert(1)>|[a](b)\n# h");
        assert!(!md.contains('<') && !md.contains('\n'), "{md}");
        assert!(md.contains("\\|") && md.contains("\\[a\\]\\(b\\)"), "{md}");
        assert_eq!(for_markdown("scene_00001"), "scene\\_00001");
    }
}
