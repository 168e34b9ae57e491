//! Tables of the dashboard's pages: one value rendered three ways, as escaped HTML, as CSV (every
//! table downloads) and as JSON (the page's live refresh replaces its rows with these).

use super::html::escape;
use serde::Serialize;

/// One cell: its text, and a link (a URL the server built) when it leads somewhere.
#[derive(Debug, Clone, Serialize)]
pub struct Cell {
    /// The text shown (and written to CSV).
    pub text: String,
    /// Where it links to.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub link: Option<String>,
    /// The stored value, when the text rounds it: what CSV exports and tables sort by.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value: Option<String>,
}

impl Cell {
    /// A plain cell.
    pub fn text(t: impl Into<String>) -> Cell {
        Cell { text: t.into(), link: None, value: None }
    }

    /// A number shown with four decimals ([`num`]), exported and sorted as stored.
    pub fn num(v: Option<f64>) -> Cell {
        Cell { text: num(v), link: None, value: v.map(|x| x.to_string()) }
    }

    /// A linked cell.
    pub fn link(t: impl Into<String>, url: impl Into<String>) -> Cell {
        Cell { text: t.into(), link: Some(url.into()), value: None }
    }
}

/// A named table of a page.
#[derive(Debug, Clone, Serialize)]
pub struct Table {
    /// Its name in `?csv=NAME` and in the page's JSON.
    pub name: String,
    /// Its heading.
    pub title: String,
    /// Column headings.
    pub columns: Vec<String>,
    /// Rows of cells, as many as columns.
    pub rows: Vec<Vec<Cell>>,
    /// Shown whole on the page, not in a scroll box (the runs list).
    pub full: bool,
}

impl Table {
    /// An empty table.
    pub fn new(name: &str, title: &str, columns: &[&str]) -> Table {
        Table {
            name: name.into(),
            title: title.into(),
            columns: columns.iter().map(|c| c.to_string()).collect(),
            rows: Vec::new(),
            full: false,
        }
    }

    /// Adds a row.
    pub fn push(&mut self, row: Vec<Cell>) {
        self.rows.push(row);
    }

    /// The table as CSV (RFC 4180 quoting).
    pub fn csv(&self) -> String {
        let line = |cells: Vec<&str>| cells.into_iter().map(csv_field).collect::<Vec<_>>().join(",");
        let mut out = line(self.columns.iter().map(String::as_str).collect());
        out.push('\n');
        for r in &self.rows {
            out.push_str(&line(r.iter().map(|c| c.value.as_deref().unwrap_or(&c.text)).collect()));
            out.push('\n');
        }
        out
    }

    /// The table as HTML, every string escaped, with its CSV link (`page` is the page's URL).
    pub fn html(&self, page: &str) -> String {
        let sep = if page.contains('?') { '&' } else { '?' };
        let mut h = format!(
            "<section><h2>{}</h2><p class=\"csv\"><a href=\"{}\">CSV</a> · {} rows</p><div class=\"{}\"><table data-table=\"{}\"><thead><tr>",
            escape(&self.title),
            escape(&format!("{page}{sep}csv={}", self.name)),
            self.rows.len(),
            if self.full { "whole" } else { "scroll" },
            escape(&self.name)
        );
        for c in &self.columns {
            h.push_str(&format!("<th>{}</th>", escape(c)));
        }
        h.push_str("</tr></thead><tbody>");
        for r in &self.rows {
            h.push_str("<tr>");
            for c in r {
                let td = match &c.value {
                    Some(v) => format!("<td data-v=\"{}\">", escape(v)),
                    None => "<td>".into(),
                };
                match &c.link {
                    Some(l) => h.push_str(&format!("{td}<a href=\"{}\">{}</a></td>", escape(l), escape(&c.text))),
                    None => h.push_str(&format!("{td}{}</td>", escape(&c.text))),
                }
            }
            h.push_str("</tr>");
        }
        h.push_str("</tbody></table></div></section>");
        h
    }
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_string() }
}

/// A number for a table: four decimals, `—` when absent.
pub fn num(v: Option<f64>) -> String {
    match v {
        Some(x) if x.is_finite() => format!("{x:.4}"),
        Some(_) => "−∞".into(),
        None => "—".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_quotes_and_html_escapes() {
        let mut t = Table::new("t", "T", &["a", "b"]);
        t.push(vec![Cell::text("x,\"y\""), Cell::link("<script>", "/run?a=<b>")]);
        assert_eq!(t.csv(), "a,b\n\"x,\"\"y\"\"\",<script>\n");
        let h = t.html("/p");
        assert!(h.contains("&lt;script&gt;") && !h.contains("<script>"), "{h}");
        assert!(h.contains("/run?a=&lt;b&gt;"), "{h}");
    }

    #[test]
    fn numbers_show_rounded_and_export_as_stored() {
        let mut t = Table::new("t", "T", &["x"]);
        t.push(vec![Cell::num(Some(0.123456789012))]);
        t.push(vec![Cell::num(None)]);
        assert_eq!(t.csv(), "x\n0.123456789012\n—\n");
        assert!(t.html("/").contains("<td data-v=\"0.123456789012\">0.1235</td>"));
    }
}
