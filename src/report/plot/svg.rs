//! SVG 1.1 backend: turns the scene primitives into plain SVG text.
//!
//! SVG is the "publication" output: vector lines and real `<text>` elements,
//! so Unicode labels (λ, η, Θ, ...) are kept as they are, only XML-escaped.

use std::fmt::Write;

use super::{Anchor, Dash, Label, Prim, Rgb};

/// Escape the characters that are special in XML text and attributes.
pub(super) fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            _ => out.push(c),
        }
    }
    out
}

fn hex(c: Rgb) -> String {
    format!("#{:02x}{:02x}{:02x}", c.0, c.1, c.2)
}

/// ` stroke-dasharray` attribute for a dashed stroke, else nothing. SVG
/// restarts the pattern at each subpath, as the raster backend does.
fn dash_attr(dash: &Dash) -> String {
    dash.map_or(String::new(), |[on, off]| {
        format!(" stroke-dasharray=\"{on} {off}\"")
    })
}

/// The primitives of one figure in a document: drawn shifted by `at` (pixels), their data
/// clipped to `frame`, the `[left, top, right, bottom]` box in the figure's own pixels.
pub(super) struct Part<'a> {
    pub(super) at: (f64, f64),
    pub(super) frame: [f64; 4],
    pub(super) prims: &'a [Prim],
}

/// Render `prims` as an SVG document of size `w` x `h`; `frame` is the
/// `[left, top, right, bottom]` box that data primitives are clipped to.
pub(super) fn render(w: u32, h: u32, frame: [f64; 4], prims: &[Prim]) -> String {
    document(w, h, &[Part { at: (0.0, 0.0), frame, prims }])
}

/// An SVG document of size `w` x `h` holding `parts`, each with a clip path of its own
/// (`plotarea` for a lone part at the origin, else `plotarea<k>` inside a translated group).
pub(super) fn document(w: u32, h: u32, parts: &[Part]) -> String {
    let clip_def = |id: &str, [l, t, r, b]: [f64; 4]| {
        format!(
            "<defs><clipPath id=\"{id}\"><rect x=\"{l:.1}\" y=\"{t:.1}\" \
             width=\"{:.1}\" height=\"{:.1}\"/></clipPath></defs>\n",
            r - l,
            b - t
        )
    };
    const BACKGROUND: &str = "<rect width=\"100%\" height=\"100%\" fill=\"#ffffff\"/>\n";
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" \
         width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\">\n"
    );
    match parts {
        [only] if only.at == (0.0, 0.0) => {
            s += &clip_def("plotarea", only.frame);
            s += BACKGROUND;
            body(&mut s, only.prims, "plotarea");
        }
        _ => {
            s += BACKGROUND;
            for (k, part) in parts.iter().enumerate() {
                let id = format!("plotarea{k}");
                let _ = writeln!(s, "<g transform=\"translate({:.2} {:.2})\">", part.at.0, part.at.1);
                s += &clip_def(&id, part.frame);
                body(&mut s, part.prims, &id);
                s.push_str("</g>\n");
            }
        }
    }
    s.push_str("</svg>\n");
    s
}

/// The elements of `prims`, data clipped to the clip path `clip_id`.
fn body(s: &mut String, prims: &[Prim], clip_id: &str) {
    let clip_attr = format!(" clip-path=\"url(#{clip_id})\"");
    let clip = clip_attr.as_str();
    // `write!` into a String cannot fail, so its Result is ignored below.
    for p in prims {
        match p {
            Prim::Path(parts, color, width, dash) => {
                let mut d = String::new();
                for part in parts {
                    for (k, (x, y)) in part.iter().enumerate() {
                        let _ = write!(d, "{}{x:.2},{y:.2} ", if k == 0 { "M" } else { "L" });
                    }
                }
                let _ = writeln!(
                    s,
                    "<path d=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"{width}\"{} \
                     stroke-linejoin=\"round\"{clip}/>",
                    d.trim_end(),
                    hex(*color),
                    dash_attr(dash)
                );
            }
            Prim::Line(a, b, color, width, dash) => {
                let _ = writeln!(
                    s,
                    "<line x1=\"{:.2}\" y1=\"{:.2}\" x2=\"{:.2}\" y2=\"{:.2}\" stroke=\"{}\" \
                     stroke-width=\"{width}\"{} shape-rendering=\"crispEdges\"/>",
                    a.0,
                    a.1,
                    b.0,
                    b.1,
                    hex(*color),
                    dash_attr(dash)
                );
            }
            Prim::Rect([x0, y0, x1, y1], fill, stroke) => {
                let fill = fill.map_or("none".to_string(), hex);
                let stroke = stroke.map_or("none".to_string(), hex);
                let _ = writeln!(
                    s,
                    "<rect x=\"{x0:.2}\" y=\"{y0:.2}\" width=\"{:.2}\" height=\"{:.2}\" \
                     fill=\"{fill}\" stroke=\"{stroke}\" shape-rendering=\"crispEdges\"/>",
                    x1 - x0,
                    y1 - y0
                );
            }
            Prim::Dots(pts, color, r, ring, clipped) => {
                let clip = if *clipped { clip } else { "" };
                let paint = if *ring {
                    format!(
                        "fill=\"none\" stroke=\"{}\" stroke-width=\"1\"",
                        hex(*color)
                    )
                } else {
                    format!("fill=\"{}\"", hex(*color))
                };
                let _ = writeln!(s, "<g {paint}{clip}>");
                for (x, y) in pts {
                    let _ = writeln!(s, "<circle cx=\"{x:.2}\" cy=\"{y:.2}\" r=\"{r}\"/>");
                }
                s.push_str("</g>\n");
            }
            Prim::Text(t) => text(s, t),
        }
    }
}

fn text(s: &mut String, t: &Label) {
    // Bitmap glyphs are 7 rows tall above the baseline; a sans-serif font of
    // about 1.45x that size has a similar cap height.
    let size = 10.0 * f64::from(t.scale);
    let anchor = match t.anchor {
        Anchor::Start => "start",
        Anchor::Middle => "middle",
        Anchor::End => "end",
    };
    let weight = if t.bold { " font-weight=\"bold\"" } else { "" };
    // (x, y) is the centre line of the text; shift to the baseline.
    let (x, y, rot) = if t.vertical {
        let x = t.x + 0.35 * size;
        (
            x,
            t.y,
            format!(" transform=\"rotate(-90 {x:.2} {:.2})\"", t.y),
        )
    } else {
        (t.x, t.y + 0.35 * size, String::new())
    };
    let _ = writeln!(
        s,
        "<text x=\"{x:.2}\" y=\"{y:.2}\" font-family=\"DejaVu Sans, Arial, Helvetica, sans-serif\" font-size=\"{size}\" fill=\"{}\" text-anchor=\"{anchor}\"{weight}{rot}>{}</text>",
        hex(t.color),
        escape(&t.text)
    );
}
