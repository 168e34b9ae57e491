//! HTML of the pages: escaping, URL encoding, and the layout every page shares. Every string read
//! from a run directory goes through [`escape`]; the script draws with `textContent` only.

/// The embedded script and style sheet: the dashboard works offline.
pub const APP_JS: &str = include_str!("assets/app.js");
/// See [`APP_JS`].
pub const STYLE_CSS: &str = include_str!("assets/style.css");

/// Escapes text for HTML content and quoted attributes.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// Percent-encodes a path segment or query value (everything but unreserved characters).
pub fn encode(s: &str) -> String {
    let mut out = String::new();
    for b in s.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

/// Encodes a relative path segment by segment, keeping its slashes.
pub fn encode_path(rel: &str) -> String {
    rel.split('/').map(encode).collect::<Vec<_>>().join("/")
}

/// Decodes percent-encoding (and `+` in queries as a space); `None` when not valid UTF-8.
pub fn decode(s: &str, plus: bool) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'%' if i + 2 < b.len() => {
                let hex = std::str::from_utf8(&b[i + 1..i + 3]).ok()?;
                out.push(u8::from_str_radix(hex, 16).ok()?);
                i += 3;
            }
            b'%' => return None,
            b'+' if plus => {
                out.push(b' ');
                i += 1;
            }
            c => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8(out).ok()
}

/// A whole page: title, breadcrumb, body, then its tables (already HTML: [`super::table`] renders
/// them with [`escape`], so this module does not depend on it back). The page's script polls its
/// JSON (`?json=1`) and redraws charts and tables without a reload.
pub fn page(title: &str, crumbs: &[(String, String)], body: &str, tables: &str, url: &str) -> String {
    let mut nav = String::from("<a href=\"/\">runs</a>");
    for (t, l) in crumbs {
        nav.push_str(&format!(" / <a href=\"{}\">{}</a>", escape(l), escape(t)));
    }
    let mut h = format!(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>{} · bfqi-ga dashboard</title>\
         <link rel=\"stylesheet\" href=\"/assets/style.css\"></head><body data-page=\"{}\">\
         <header><nav>{nav}</nav><span id=\"live\" class=\"live\"></span></header><main><h1>{}</h1>{body}",
        escape(title),
        escape(url),
        escape(title)
    );
    h.push_str(tables);
    h.push_str("</main><script src=\"/assets/app.js\"></script></body></html>");
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encoding_round_trips_and_escape_covers_quotes() {
        let s = "a b/<c>&'\"é";
        assert_eq!(decode(&encode(s), false).as_deref(), Some(s));
        assert_eq!(decode("%2", false), None);
        assert_eq!(escape("<a href='x'>"), "&lt;a href=&#39;x&#39;&gt;");
    }
}
