//! Element nesting measured before the XML parser sees the text: the parser (and our reading
//! of nested BSDFs and textures) recurses once per level, so a file nested thousands deep
//! would overflow the stack and abort the process instead of giving an error.

/// Deepest element nesting a scene may have; real Mitsuba files stay below ten.
pub const MAX_XML_DEPTH: usize = 100;

/// The line (1-based) of the first element nested deeper than `limit`, if any. Comments,
/// CDATA, processing instructions and declarations are skipped; quotes inside tags are
/// honoured, so a `>` in an attribute value does not end its tag.
pub fn too_deep_at(text: &str, limit: usize) -> Option<usize> {
    let b = text.as_bytes();
    let mut depth = 0usize;
    let mut i = 0;
    let skip_past = |from: usize, end: &[u8]| -> usize {
        b[from..].windows(end.len()).position(|w| w == end).map_or(b.len(), |k| from + k + end.len())
    };
    while let Some(k) = b[i..].iter().position(|&c| c == b'<') {
        let start = i + k;
        let rest = &b[start..];
        if rest.starts_with(b"<!--") {
            i = skip_past(start + 4, b"-->");
        } else if rest.starts_with(b"<![CDATA[") {
            i = skip_past(start + 9, b"]]>");
        } else if rest.starts_with(b"<?") {
            i = skip_past(start + 2, b"?>");
        } else {
            // A tag: find its closing '>' outside quotes.
            let mut j = start + 1;
            let mut quote = None;
            while j < b.len() {
                match (quote, b[j]) {
                    (None, b'"' | b'\'') => quote = Some(b[j]),
                    (Some(q), c) if c == q => quote = None,
                    (None, b'>') => break,
                    _ => {}
                }
                j += 1;
            }
            let closing = rest.starts_with(b"</");
            let declaration = rest.starts_with(b"<!");
            let empty = j > start + 1 && b.get(j - 1) == Some(&b'/');
            if closing {
                depth = depth.saturating_sub(1);
            } else if !declaration && !empty {
                depth += 1;
                if depth > limit {
                    return Some(1 + b[..start].iter().filter(|&&c| c == b'\n').count());
                }
            }
            i = (j + 1).min(b.len());
        }
        if i >= b.len() {
            break;
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::too_deep_at;

    #[test]
    fn counts_open_elements_only() {
        let flat = "<scene><a/><b x='>'>t</b><!-- <c><c><c> --><![CDATA[<d><d>]]><?p <e><e>?></scene>";
        assert_eq!(too_deep_at(flat, 2), None);
        assert_eq!(too_deep_at(flat, 1), Some(1));
        let deep = format!("<scene>\n{}{}</scene>", "<x>".repeat(5), "</x>".repeat(5));
        assert_eq!(too_deep_at(&deep, 6), None);
        assert_eq!(too_deep_at(&deep, 5), Some(2));
    }
}
