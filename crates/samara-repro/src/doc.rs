//! A tiny document model rendered to Markdown and to self-contained HTML, so the two
//! reports always say the same thing.

use std::fmt::Write as _;

/// One block of a report.
#[derive(Clone, Debug, PartialEq)]
pub enum Block {
    /// A heading of level 1..3.
    Heading(u8, String),
    /// A paragraph (plain text; `code` spans in backticks are rendered).
    Para(String),
    /// A bullet list.
    List(Vec<String>),
    /// A table.
    Table {
        /// Column titles.
        header: Vec<String>,
        /// Rows.
        rows: Vec<Vec<String>>,
    },
    /// A figure: a path relative to the report and a caption.
    Image {
        /// Relative path.
        path: String,
        /// Caption.
        caption: String,
    },
    /// Preformatted text.
    Code(String),
}

/// A report.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Document {
    /// Title.
    pub title: String,
    /// Body.
    pub blocks: Vec<Block>,
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn inline_html(s: &str) -> String {
    // Backtick spans -> <code>.
    let mut out = String::new();
    for (i, part) in s.split('`').enumerate() {
        if i % 2 == 1 {
            let _ = write!(out, "<code>{}</code>", esc(part));
        } else {
            out.push_str(&esc(part));
        }
    }
    out
}

impl Document {
    /// A new empty document.
    pub fn new(title: impl Into<String>) -> Self {
        Document {
            title: title.into(),
            blocks: Vec::new(),
        }
    }

    /// Append a block.
    pub fn push(&mut self, b: Block) {
        self.blocks.push(b);
    }

    /// Paths of every image the document references.
    pub fn images(&self) -> Vec<&str> {
        self.blocks
            .iter()
            .filter_map(|b| match b {
                Block::Image { path, .. } => Some(path.as_str()),
                _ => None,
            })
            .collect()
    }

    /// Render as Markdown.
    pub fn to_markdown(&self) -> String {
        let mut s = format!("# {}\n\n", self.title);
        for b in &self.blocks {
            match b {
                Block::Heading(l, t) => {
                    let _ = writeln!(s, "{} {t}\n", "#".repeat(*l as usize + 1));
                }
                Block::Para(t) => {
                    let _ = writeln!(s, "{t}\n");
                }
                Block::List(items) => {
                    for i in items {
                        let _ = writeln!(s, "- {i}");
                    }
                    s.push('\n');
                }
                Block::Table { header, rows } => {
                    let _ = writeln!(s, "| {} |", header.join(" | "));
                    let _ = writeln!(s, "|{}", "---|".repeat(header.len()));
                    for r in rows {
                        let _ = writeln!(s, "| {} |", r.join(" | "));
                    }
                    s.push('\n');
                }
                Block::Image { path, caption } => {
                    let _ = writeln!(s, "![{caption}]({path})\n\n*{caption}*\n");
                }
                Block::Code(t) => {
                    let _ = writeln!(s, "```\n{t}\n```\n");
                }
            }
        }
        s
    }

    /// Render as a standalone HTML page (images referenced by relative path).
    pub fn to_html(&self) -> String {
        let mut s = String::new();
        let _ = write!(
            s,
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title>\n<style>\
body{{font-family:sans-serif;max-width:1000px;margin:2em auto;padding:0 1em;line-height:1.45;color:#222}}\
table{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #bbb;padding:.3em .6em;text-align:right}}\
th{{background:#eee}}td:first-child,th:first-child{{text-align:left}}img{{max-width:100%;border:1px solid #ddd}}\
figure{{margin:1em 0}}figcaption{{font-style:italic;color:#555}}code,pre{{background:#f4f4f4}}pre{{padding:.6em;overflow-x:auto}}\
</style></head><body>\n<h1>{}</h1>\n",
            esc(&self.title),
            esc(&self.title)
        );
        for b in &self.blocks {
            match b {
                Block::Heading(l, t) => {
                    let _ = writeln!(s, "<h{0}>{1}</h{0}>", l + 1, inline_html(t));
                }
                Block::Para(t) => {
                    let _ = writeln!(s, "<p>{}</p>", inline_html(t));
                }
                Block::List(items) => {
                    s.push_str("<ul>\n");
                    for i in items {
                        let _ = writeln!(s, "<li>{}</li>", inline_html(i));
                    }
                    s.push_str("</ul>\n");
                }
                Block::Table { header, rows } => {
                    s.push_str("<table><thead><tr>");
                    for h in header {
                        let _ = write!(s, "<th>{}</th>", inline_html(h));
                    }
                    s.push_str("</tr></thead><tbody>\n");
                    for r in rows {
                        s.push_str("<tr>");
                        for c in r {
                            let _ = write!(s, "<td>{}</td>", inline_html(c));
                        }
                        s.push_str("</tr>\n");
                    }
                    s.push_str("</tbody></table>\n");
                }
                Block::Image { path, caption } => {
                    let _ = writeln!(
                        s,
                        "<figure><img src=\"{}\" alt=\"{}\"><figcaption>{}</figcaption></figure>",
                        esc(path),
                        esc(caption),
                        inline_html(caption)
                    );
                }
                Block::Code(t) => {
                    let _ = writeln!(s, "<pre>{}</pre>", esc(t));
                }
            }
        }
        s.push_str("</body></html>\n");
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn html_escapes_and_renders_code_spans() {
        let mut d = Document::new("R & D");
        d.push(Block::Para("a `x < y` b".into()));
        d.push(Block::Table {
            header: vec!["k".into()],
            rows: vec![vec!["<v>".into()]],
        });
        let h = d.to_html();
        assert!(h.contains("<title>R &amp; D</title>"));
        assert!(h.contains("<code>x &lt; y</code>"));
        assert!(h.contains("<td>&lt;v&gt;</td>"));
        let m = d.to_markdown();
        assert!(m.contains("| k |") && m.contains("a `x < y` b"));
    }
}
