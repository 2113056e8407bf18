//! Tests: checksums, an independent INFLATE decoder for round trips, an
//! external check with python3's zlib when available, and rendering checks.

use super::*;
use std::f64::consts::{PI, TAU};

// ---- A minimal INFLATE decoder (stored and fixed-Huffman blocks only) ----
// Its RFC 1951 tables are copied from the RFC, not imported from the encoder: a wrong
// table there must not pass its own round trip.

const LEN_BASE: [u32; 29] = [
    3, 4, 5, 6, 7, 8, 9, 10, 11, 13, 15, 17, 19, 23, 27, 31, 35, 43, 51, 59, 67, 83, 99, 115, 131,
    163, 195, 227, 258,
];
const LEN_EXTRA: [u32; 29] = [
    0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0,
];
const DIST_BASE: [u32; 30] = [
    1, 2, 3, 4, 5, 7, 9, 13, 17, 25, 33, 49, 65, 97, 129, 193, 257, 385, 513, 769, 1025, 1537,
    2049, 3073, 4097, 6145, 8193, 12289, 16385, 24577,
];
const DIST_EXTRA: [u32; 30] = [
    0, 0, 0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6, 7, 7, 8, 8, 9, 9, 10, 10, 11, 11, 12, 12, 13,
    13,
];

struct BitReader<'a> {
    d: &'a [u8],
    pos: usize,
}

impl BitReader<'_> {
    fn bit(&mut self) -> Result<u32, String> {
        let byte = *self
            .d
            .get(self.pos / 8)
            .ok_or("unexpected end of deflate data")?;
        self.pos += 1;
        Ok(u32::from(byte >> ((self.pos - 1) % 8)) & 1)
    }
    /// Plain values are stored LSB-first.
    fn bits(&mut self, n: u32) -> Result<u32, String> {
        (0..n).try_fold(0, |v, i| Ok(v | self.bit()? << i))
    }
    /// Huffman codes are stored MSB-first.
    fn code(&mut self, n: u32) -> Result<u32, String> {
        (0..n).try_fold(0, |v, _| Ok(v << 1 | self.bit()?))
    }
    fn fixed_symbol(&mut self) -> Result<u32, String> {
        let c = self.code(7)?;
        if c <= 0x17 {
            return Ok(256 + c);
        }
        let c = c << 1 | self.bit()?;
        match c {
            0x30..=0xBF => return Ok(c - 0x30),
            0xC0..=0xC7 => return Ok(280 + c - 0xC0),
            _ => {}
        }
        let c = c << 1 | self.bit()?;
        if (0x190..=0x1FF).contains(&c) {
            Ok(144 + c - 0x190)
        } else {
            Err(format!("bad code {c:#x}"))
        }
    }
}

/// Decode a raw deflate stream; returns the data and the bytes consumed.
fn inflate(d: &[u8]) -> Result<(Vec<u8>, usize), String> {
    let mut br = BitReader { d, pos: 0 };
    let mut out: Vec<u8> = Vec::new();
    loop {
        let last = br.bits(1)?;
        match br.bits(2)? {
            0 => {
                br.pos = br.pos.div_ceil(8) * 8;
                let (len, nlen) = (br.bits(16)?, br.bits(16)?);
                if len != !nlen & 0xFFFF {
                    return Err("stored block LEN/NLEN mismatch".into());
                }
                for _ in 0..len {
                    out.push(br.bits(8)? as u8);
                }
            }
            1 => loop {
                let sym = br.fixed_symbol()?;
                match sym {
                    0..=255 => out.push(sym as u8),
                    256 => break,
                    257..=285 => {
                        let i = (sym - 257) as usize;
                        let len = LEN_BASE[i] + br.bits(LEN_EXTRA[i])?;
                        let dc = br.code(5)? as usize;
                        let dist = *DIST_BASE.get(dc).ok_or("bad distance code")? as usize;
                        let dist = dist + br.bits(DIST_EXTRA[dc])? as usize;
                        if dist > out.len() || dist > 32768 {
                            return Err(format!("distance {dist} too far back"));
                        }
                        for _ in 0..len {
                            out.push(out[out.len() - dist]);
                        }
                    }
                    _ => return Err(format!("invalid symbol {sym}")),
                }
            },
            t => return Err(format!("unsupported block type {t}")),
        }
        if last == 1 {
            return Ok((out, br.pos.div_ceil(8)));
        }
    }
}

fn zlib_decode(d: &[u8]) -> Result<Vec<u8>, String> {
    if d.len() < 6 || d[0] & 0x0F != 8 || (u32::from(d[0]) * 256 + u32::from(d[1])) % 31 != 0 {
        return Err("bad zlib header".into());
    }
    let (out, used) = inflate(&d[2..])?;
    let tail = d.get(2 + used..2 + used + 4).ok_or("missing Adler-32")?;
    if u32::from_be_bytes([tail[0], tail[1], tail[2], tail[3]]) != png::adler32(&out) {
        return Err("Adler-32 mismatch".into());
    }
    Ok(out)
}

/// Check signature and chunk CRCs; return (width, height, IDAT bytes).
fn parse_png(p: &[u8]) -> Result<(u32, u32, Vec<u8>), String> {
    if p.get(..8) != Some(&[0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1A, b'\n'][..]) {
        return Err("bad signature".into());
    }
    let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
    let (mut pos, mut size, mut idat, mut kinds) = (8, (0, 0), Vec::new(), Vec::new());
    while pos < p.len() {
        let n = be(p.get(pos..pos + 4).ok_or("truncated")?) as usize;
        let body = p.get(pos + 4..pos + 8 + n).ok_or("truncated chunk")?;
        let crc = be(p.get(pos + 8 + n..pos + 12 + n).ok_or("missing CRC")?);
        if png::crc32(body) != crc {
            return Err("chunk CRC mismatch".into());
        }
        let (kind, data) = body.split_at(4);
        match kind {
            b"IHDR" => {
                size = (be(&data[0..4]), be(&data[4..8]));
                assert_eq!(&data[8..13], &[8, 2, 0, 0, 0]);
            }
            b"IDAT" => idat.extend_from_slice(data),
            _ => {}
        }
        kinds.push(kind.to_vec());
        pos += 12 + n;
    }
    assert_eq!(kinds.first().map(|k| k.as_slice()), Some(&b"IHDR"[..]));
    assert_eq!(kinds.last().map(|k| k.as_slice()), Some(&b"IEND"[..]));
    Ok((size.0, size.1, idat))
}

/// Undo PNG filters 0 and 1.
fn unfilter(w: u32, raw: &[u8]) -> Vec<u8> {
    let stride = 3 * w as usize;
    let mut out = Vec::new();
    for row in raw.chunks(stride + 1) {
        let start = out.len();
        for (i, &b) in row[1..].iter().enumerate() {
            let left = if row[0] == 1 && i >= 3 {
                out[start + i - 3]
            } else {
                0
            };
            out.push(b.wrapping_add(left));
        }
        assert!(row[0] <= 1, "unexpected filter type {}", row[0]);
    }
    out
}

fn sine_figure() -> Figure {
    let xs: Vec<f64> = (0..=500).map(|i| f64::from(i) * TAU / 500.0).collect();
    let ys: Vec<f64> = xs.iter().map(|x| x.sin()).collect();
    let mut fig = Figure::new("Sine wave λ & <test>")
        .x_range(0.0, TAU)
        .y_range(-1.5, 1.5)
        .x_label("x")
        .y_label("sin x");
    fig.series("sin", &xs, &ys, Marker::Line);
    fig.series(
        "cos",
        &xs,
        &xs.iter().map(|x| x.cos()).collect::<Vec<_>>(),
        Marker::Line,
    );
    fig.hline(0.0);
    fig
}

// ---- Tests ----

#[test]
fn checksums_match_known_values() {
    assert_eq!(png::crc32(b"123456789"), 0xCBF4_3926);
    assert_eq!(png::crc32(b""), 0);
    assert_eq!(png::crc32(b"IEND"), 0xAE42_6082);
    assert_eq!(png::adler32(b"Wikipedia"), 0x11E6_0398);
    assert_eq!(png::adler32(b""), 1);
    // Long input exercises the modulo chunking against a naive reference.
    let data: Vec<u8> = (0..100_000u32)
        .map(|i| (i * 7 + 255) as u8 | 0xF0)
        .collect();
    let (mut a, mut b) = (1u64, 0u64);
    for &x in &data {
        a = (a + u64::from(x)) % 65521;
        b = (b + a) % 65521;
    }
    assert_eq!(u64::from(png::adler32(&data)), b << 16 | a);
}

#[test]
fn test_inflater_reads_stored_blocks() {
    // zlib header, stored final block "hi", Adler-32 of "hi".
    let mut z = vec![0x78, 0x01, 0x01, 0x02, 0x00, 0xFD, 0xFF, b'h', b'i'];
    z.extend_from_slice(&png::adler32(b"hi").to_be_bytes());
    assert_eq!(zlib_decode(&z), Ok(b"hi".to_vec()));
    z[5] = 0; // corrupt NLEN
    assert!(zlib_decode(&z).is_err());
}

#[test]
fn deflate_round_trips() {
    let mut seed = 0x2545_F491_4F6C_DD1Du64;
    let mut rand = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed as u8
    };
    let noise: Vec<u8> = (0..40_000).map(|_| rand()).collect();
    let far_repeat = [noise.clone(), noise.clone()].concat(); // repeat beyond the 32 KiB window
    let mut cases: Vec<Vec<u8>> = vec![
        vec![],
        vec![42],
        vec![7, 7],
        b"abcabcabcabcabcabcabcabd".to_vec(),
        vec![0xFF; 100_000],
        (0..70_000u32).map(|i| (i % 251) as u8).collect(),
        noise,
        far_repeat,
    ];
    cases.push(
        (0..5000)
            .map(|i| if i % 300 < 290 { 0 } else { rand() })
            .collect(),
    );
    for (k, data) in cases.iter().enumerate() {
        let z = png::zlib(data);
        assert_eq!(zlib_decode(&z).as_ref(), Ok(data), "case {k}");
    }
    // Compression actually happens on repetitive data.
    assert!(png::zlib(&vec![0xFF; 100_000]).len() < 1000);
}

#[test]
fn png_round_trip_reproduces_scanlines() {
    let fig = sine_figure();
    let canvas = fig.raster();
    let raw = png::filter_rows(canvas.w, canvas.h, &canvas.px);
    let bytes = fig.to_png();
    let (w, h, idat) = parse_png(&bytes).expect("valid PNG structure");
    assert_eq!((w, h), (900, 600));
    let decoded = zlib_decode(&idat).expect("valid zlib stream");
    assert_eq!(decoded.len(), (h * (1 + 3 * w)) as usize);
    assert!(
        decoded == raw,
        "IDAT does not reproduce the filtered scanlines"
    );
    assert!(
        unfilter(w, &decoded) == canvas.px,
        "unfiltered pixels differ from the canvas"
    );
    assert!(
        bytes.len() < 150_000,
        "PNG too large: {} bytes",
        bytes.len()
    );
}

#[test]
fn python_zlib_accepts_png() {
    if std::process::Command::new("python3")
        .arg("--version")
        .output()
        .is_err()
    {
        eprintln!("python3 not available; skipping external PNG check");
        return;
    }
    let dir = std::env::temp_dir().join(format!("plotdev-test-{}", std::process::id()));
    let fig = sine_figure().size(640, 480);
    fig.save(&dir, "sine").expect("write figure");
    let script = "import zlib,struct,sys\n\
        d=open(sys.argv[1],'rb').read()\n\
        assert d[:8]==b'\\x89PNG\\r\\n\\x1a\\n'\n\
        p=8; idat=b''; kinds=[]\n\
        while p<len(d):\n\
        \x20   n,=struct.unpack('>I',d[p:p+4]); t=d[p+4:p+8]; c=d[p+8:p+8+n]\n\
        \x20   assert zlib.crc32(t+c)&0xffffffff==struct.unpack('>I',d[p+8+n:p+12+n])[0], t\n\
        \x20   if t==b'IHDR': w,h,bd,ct=struct.unpack('>IIBB',c[:10]); assert (bd,ct)==(8,2)\n\
        \x20   if t==b'IDAT': idat+=c\n\
        \x20   kinds.append(t); p+=12+n\n\
        assert kinds[0]==b'IHDR' and kinds[-1]==b'IEND'\n\
        raw=zlib.decompress(idat)\n\
        assert len(raw)==h*(1+3*w), (len(raw), w, h)\n\
        assert all(raw[r*(1+3*w)] in (0,1) for r in range(h))\n\
        print('ok', w, h)\n";
    let out = std::process::Command::new("python3")
        .arg("-c")
        .arg(script)
        .arg(dir.join("sine.png"))
        .output();
    let _ = std::fs::remove_dir_all(&dir);
    let out = out.expect("run python3");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "python check failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(stdout.trim(), "ok 640 480");
}

#[test]
fn sine_curve_and_title_are_drawn() {
    let fig = sine_figure();
    let lay = fig.layout();
    let c = fig.raster();
    let near = |px: f64, py: f64, col: Rgb| {
        let (x, y) = (px.round() as i64, py.round() as i64);
        (-2..=2).any(|dy| (-2..=2).any(|dx| c.get((x + dx) as u32, (y + dy) as u32) == col))
    };
    for x in [0.3, 1.0, PI / 2.0, 2.5, 4.0, 4.7, 5.5] {
        let (px, py) = lay.map((x, f64::sin(x)));
        assert!(near(px, py, PALETTE[0]), "no curve pixel near x = {x}");
    }
    // Away from both curves and the zero line the plot area stays white.
    let (px, py) = lay.map((PI / 2.0, -1.2));
    assert!(
        !near(px, py, PALETTE[0]) && near(px, py, WHITE) && c.get(px as u32, py as u32) == WHITE
    );
    // Title text: dark pixels in the band above the frame.
    // (Only the middle columns: the top y tick label may reach above the frame.)
    let dark = |c: &raster::Canvas, y_max: u32| {
        let cols = c.w / 4..3 * c.w / 4;
        (0..y_max)
            .flat_map(|y| cols.clone().map(move |x| (x, y)))
            .filter(|&(x, y)| c.get(x, y).0 < 80)
            .count()
    };
    assert!(dark(&c, lay.t as u32 - 2) > 100, "title not drawn");
    let untitled = Figure::new("");
    let blank = untitled.raster();
    assert_eq!(dark(&blank, untitled.layout().t as u32 - 2), 0);
}

#[test]
fn svg_is_well_formed() {
    let mut fig = sine_figure();
    fig.series("dots", &[1.0, 2.0], &[0.5, 0.2], Marker::Points);
    let s = fig.to_svg();
    assert!(s.starts_with("<svg"));
    assert!(s.trim_end().ends_with("</svg>"));
    assert!(s.contains(">Sine wave λ &amp; &lt;test&gt;</text>"));
    assert_eq!(
        s.matches("<path").count(),
        2,
        "one path per line series:\n{s}"
    );
    assert_eq!(
        s.matches("<circle").count(),
        3,
        "two data dots and one legend dot"
    );
    assert_eq!(s.matches("<text").count(), s.matches("</text>").count());
    let mut h = Figure::new("\"q\"");
    h.histogram("h", &[0.1, 0.2, 0.25, 0.9], 4, 0.0, 1.0, true);
    let s = h.to_svg();
    assert!(s.contains("&quot;q&quot;") && s.matches("<path").count() == 1);
}

#[test]
fn nonfinite_and_empty_data_do_not_panic() {
    let (nan, inf) = (f64::NAN, f64::INFINITY);
    let mut fig = Figure::new("bad data").x_range(nan, 1.0).y_range(inf, -inf);
    fig.series(
        "nan",
        &[0.0, nan, 2.0, 3.0, inf],
        &[1.0, 2.0, nan, 4.0, 5.0],
        Marker::Line,
    );
    fig.series("empty", &[], &[], Marker::LinePoints);
    fig.series("all nan", &[nan, nan], &[nan, inf], Marker::Steps);
    fig.series("huge", &[0.0, 1.0], &[-1e300, 1e300], Marker::Points);
    fig.histogram("h", &[nan, inf, 0.5], 0, 0.0, 1.0, true);
    fig.histogram("h2", &[nan, inf], 10, 1.0, nan, false);
    fig.arrows("arr", &[(0.0, 0.0), (nan, 1.0)], &[(1.0, 1.0), (0.0, 0.0)]);
    fig.hline(nan).hline(1e308);
    let s = fig.to_svg();
    assert!(!s.contains("NaN") && !s.contains("inf"));
    for f in [fig, Figure::new(""), Figure::new("tiny").size(0, 0)] {
        let bytes = f.to_png();
        let (w, _, idat) = parse_png(&bytes).expect("valid PNG");
        assert!(zlib_decode(&idat).is_ok() && w >= 120);
    }
    // Extremely large or tiny ranges still give finite, labelled ticks.
    let mut e = Figure::new("extreme");
    e.series("", &[-f64::MAX, f64::MAX], &[1e-300, 2e-300], Marker::Line);
    let lay = e.layout();
    assert!(lay.x.0.is_finite() && lay.x.1.is_finite() && !lay.yticks.is_empty());
    let _ = e.to_png();
}

#[test]
fn ranges_ticks_and_labels() {
    assert_eq!(axis_range(None, None), (0.0, 1.0));
    assert_eq!(axis_range(None, Some((2.0, 2.0))), (1.8, 2.2));
    assert_eq!(axis_range(None, Some((0.0, 0.0))), (-1.0, 1.0));
    assert_eq!(axis_range(Some((3.0, 1.0)), Some((0.0, 9.0))), (1.0, 3.0));
    let (lo, hi) = axis_range(None, Some((0.0, 100.0)));
    assert!((lo + 3.0).abs() < 1e-12 && (hi - 103.0).abs() < 1e-12);
    assert_eq!(nice_step(1.0, 5), 0.2);
    assert_eq!(nice_step(70.0, 6), 20.0);
    let labels: Vec<String> = ticks(-0.03, 1.03, 0.2).into_iter().map(|t| t.1).collect();
    assert_eq!(labels, ["0", "0.2", "0.4", "0.6", "0.8", "1.0"]);
    let labels: Vec<String> = ticks(-1.5, 1.5, 0.5).into_iter().map(|t| t.1).collect();
    assert_eq!(labels, ["-1.5", "-1.0", "-0.5", "0", "0.5", "1.0", "1.5"]);
    assert_eq!(fmt_tick(2e-5, 1e-5, true), "2e-5");
    assert_eq!(fmt_tick(150_000.0, 50_000.0, true), "1.5e5");
    let labels: Vec<String> = ticks(9.488e5, 9.502e5, 500.0).into_iter().map(|t| t.1).collect();
    assert_eq!(labels, ["9.490e5", "9.495e5", "9.500e5"], "one mantissa length per axis");
    let labels: Vec<String> = ticks(9.0e5, 1.0e6, 2e4).into_iter().map(|t| t.1).collect();
    assert_eq!(labels, ["9.0e5", "9.2e5", "9.4e5", "9.6e5", "9.8e5", "1.0e6"], "the Henon preset's window");
    let labels: Vec<String> = ticks(0.0, 2.5e5, 5e4).into_iter().map(|t| t.1).collect();
    assert_eq!(labels, ["0", "5.0e4", "1.0e5", "1.5e5", "2.0e5", "2.5e5"]);
    assert_eq!(fmt_tick(250.0, 50.0, false), "250");
    // One notation per axis: the Henon run's 2e4..1e5 was "20000 .. 80000, 1e5".
    let labels: Vec<String> = ticks(1e4, 1.05e5, 2e4).into_iter().map(|t| t.1).collect();
    assert_eq!(labels, ["2e4", "4e4", "6e4", "8e4", "1e5"]);
    let labels: Vec<String> = ticks(0.0, 9e4, 2e4).into_iter().map(|t| t.1).collect();
    assert_eq!(labels, ["0", "20000", "40000", "60000", "80000"]);
    let labels: Vec<String> = ticks(0.0, 9e-4, 2e-4).into_iter().map(|t| t.1).collect();
    assert_eq!(labels, ["0", "2e-4", "4e-4", "6e-4", "8e-4"]);
    // Automatic y ticks on a degenerate series are present and distinct.
    let mut f = Figure::new("flat");
    f.series("", &[0.0, 1.0, 2.0], &[5.0, 5.0, 5.0], Marker::Line);
    let lay = f.layout();
    assert!(lay.y.0 < 5.0 && lay.y.1 > 5.0 && lay.yticks.len() >= 3);
}

#[test]
fn histogram_density_integrates_to_one() {
    let values: Vec<f64> = (0..1000).map(|i| (f64::from(i) * 0.618).fract()).collect();
    let mut fig = Figure::new("h");
    fig.histogram("", &values, 20, 0.0, 1.0, true);
    let Kind::Xy(pts, _) = &fig.series[0].kind else {
        panic!("histogram is an outline")
    };
    assert_eq!(pts.len(), 2 * 20 + 2);
    let area: f64 = pts[1..pts.len() - 1]
        .chunks(2)
        .map(|p| (p[1].0 - p[0].0) * p[0].1)
        .sum();
    assert!((area - 1.0).abs() < 1e-12, "area {area}");
}

#[test]
fn non_ascii_labels_are_spelled_out_for_png() {
    assert_eq!(
        font::to_ascii("λ_1 ⟨η⟩ Θ μαβτ ✓"),
        "lambda_1 <eta> Theta mualphabetatau ?"
    );
    assert_eq!(font::glyph('é'), font::glyph('?'));
    assert_eq!(font::text_width("ab", 2), 22);
}

/// Pixel colours in the square of half-width `rad` around `p`.
fn colours_near(c: &raster::Canvas, p: (f64, f64), rad: i64) -> Vec<Rgb> {
    let (x, y) = (p.0.round() as i64, p.1.round() as i64);
    (-rad..=rad)
        .flat_map(|dy| (-rad..=rad).map(move |dx| (x + dx, y + dy)))
        .map(|(x, y)| c.get(x as u32, y as u32))
        .collect()
}

fn inside(p: (f64, f64), bx: [f64; 4]) -> bool {
    p.0 >= bx[0] && p.0 <= bx[2] && p.1 >= bx[1] && p.1 <= bx[3]
}

/// A fit line in the bottom-left and one point at `corner` (data in [0, 1]).
fn corner_figure(corners: &[(f64, f64)]) -> Figure {
    let mut fig = Figure::new("dispersion")
        .x_range(0.0, 1.0)
        .y_range(0.0, 1.0);
    let (xs, ys): (Vec<f64>, Vec<f64>) = corners.iter().copied().unzip();
    fig.series("measured", &xs, &ys, Marker::Points);
    fig.series("fit", &[0.3, 0.5], &[0.4, 0.5], Marker::Line);
    fig
}

#[test]
fn legend_keeps_top_right_corner_when_free() {
    let lay = sine_figure().layout();
    let [x0, y0, x1, y1] = lay.legend.expect("two labelled series");
    assert!(x1 == lay.r - 10.0 && y0 == lay.t + 10.0 && x0 > lay.l && y1 < lay.b);
    assert!(Figure::new("one").layout().legend.is_none());
}

#[test]
fn legend_moves_off_a_point_in_the_top_right_corner() {
    let fig = corner_figure(&[(0.97, 0.97)]);
    let lay = fig.layout();
    let bx = lay.legend.expect("legend");
    let p = lay.map((0.97, 0.97));
    let grown = [bx[0] - 5.0, bx[1] - 5.0, bx[2] + 5.0, bx[3] + 5.0];
    assert!(!inside(p, grown), "point {p:?} under legend {bx:?}");
    // Still an inside corner (top-left: the fit line is in the middle).
    assert!(bx[0] == lay.l + 10.0 && bx[1] == lay.t + 10.0, "{bx:?}");
    // And the point is really painted.
    let c = fig.raster();
    assert!(colours_near(&c, p, 1).contains(&PALETTE[0]));
}

#[test]
fn legend_goes_outside_when_every_corner_has_data() {
    let corners = [(0.97, 0.97), (0.03, 0.97), (0.97, 0.03), (0.03, 0.03)];
    let fig = corner_figure(&corners);
    let lay = fig.layout();
    let bx = lay.legend.expect("legend");
    assert!(
        bx[0] > lay.r && bx[2] <= f64::from(fig.w),
        "not right of the axes: {bx:?}"
    );
    assert!(
        lay.r < fig.frame_layout(0.0, 0.0).r,
        "axis box not narrowed"
    );
    let c = fig.raster();
    for p in corners {
        assert!(
            colours_near(&c, lay.map(p), 1).contains(&PALETTE[0]),
            "{p:?} hidden"
        );
    }
    // A legend too wide to sit beside the axes goes below them instead.
    let mut wide = corner_figure(&corners);
    wide.series(&"very long label ".repeat(6), &[], &[], Marker::Line);
    let lay = wide.layout();
    let bx = lay.legend.expect("legend");
    assert!(
        bx[1] > lay.x_label_y && bx[3] <= f64::from(wide.h),
        "{bx:?}"
    );
    assert!(lay.r == wide.frame_layout(0.0, 0.0).r);
}

#[test]
fn legend_avoids_curve_crossing_a_corner() {
    // A rising line passes through the top-right and bottom-left corners.
    let mut fig = Figure::new("peak").x_range(0.0, 1.0).y_range(0.0, 1.0);
    fig.series("up", &[0.0, 1.0], &[0.0, 1.0], Marker::Line);
    fig.series("flat", &[0.0, 1.0], &[0.5, 0.5], Marker::Line);
    let lay = fig.layout();
    let bx = lay.legend.expect("legend");
    assert!(
        bx[0] == lay.l + 10.0 && bx[1] == lay.t + 10.0,
        "top-left expected: {bx:?}"
    );
}

#[test]
fn coinciding_series_both_stay_visible() {
    let xs: Vec<f64> = (0..50).map(f64::from).collect();
    let ys: Vec<f64> = xs.iter().map(|x| (x / 8.0).sin()).collect();
    for marker in [
        Marker::Line,
        Marker::Points,
        Marker::LinePoints,
        Marker::Steps,
    ] {
        let mut fig = Figure::new("same");
        for name in ["a", "b", "c"] {
            fig.series(name, &xs, &ys, marker);
        }
        let c = fig.raster();
        let lay = fig.layout();
        let [l, t, r, b] = lay.frame().map(|v| v as u32);
        let legend = lay.legend.expect("legend");
        for col in &PALETTE[..3] {
            let seen = (t + 1..b)
                .flat_map(|y| (l + 1..r).map(move |x| (x, y)))
                .filter(|&(x, y)| !inside((f64::from(x), f64::from(y)), legend))
                .any(|(x, y)| c.get(x, y) == *col);
            assert!(seen, "{marker:?}: series colour {col:?} hidden");
        }
    }
}

/// Value of attribute `name` in the SVG element `el`, if present.
fn attr<'a>(el: &'a str, name: &str) -> Option<&'a str> {
    let start = el.find(&format!(" {name}=\""))? + name.len() + 3;
    el[start..].split('"').next()
}

/// SVG elements (one a line) drawn in colour `col`, as stroke or fill.
fn svg_elements<'a>(svg: &'a str, tag: &str, col: Rgb) -> Vec<&'a str> {
    let hex = format!("#{:02x}{:02x}{:02x}", col.0, col.1, col.2);
    svg.lines()
        .filter(|l| l.starts_with(tag))
        .filter(|l| attr(l, "stroke") == Some(&hex) || attr(l, "fill") == Some(&hex))
        .collect()
}

/// Beyond three coinciding series (see `pen`): every series keeps pixels of
/// its own colour in the PNG, its own SVG element, and a legend sample drawn
/// like it (the same dash pattern, the same marker).
#[test]
fn five_or_six_coinciding_series_all_stay_visible() {
    let xs: Vec<f64> = (0..50).map(f64::from).collect();
    let ys: Vec<f64> = xs.iter().map(|x| (x / 8.0).sin()).collect();
    for n in [5, 6] {
        for marker in [
            Marker::Line,
            Marker::Points,
            Marker::LinePoints,
            Marker::Steps,
        ] {
            let mut fig = Figure::new("same");
            for k in 0..n {
                fig.series(&format!("series {k}"), &xs, &ys, marker);
            }
            let what = format!("{n} x {marker:?}");
            // PNG: every series' exact colour is painted in the plot area.
            let c = fig.raster();
            let lay = fig.layout();
            let [l, t, r, b] = lay.frame().map(|v| v as u32);
            let legend = lay.legend.expect("legend");
            for (k, col) in PALETTE[..n].iter().enumerate() {
                let count = (t + 1..b)
                    .flat_map(|y| (l + 1..r).map(move |x| (x, y)))
                    .filter(|&(x, y)| !inside((f64::from(x), f64::from(y)), legend))
                    .filter(|&(x, y)| c.get(x, y) == *col)
                    .count();
                assert!(count > 0, "{what}: series {k} hidden in the PNG");
            }
            // SVG: each series has its own element(s); lines from the fourth
            // series on are dashed, each with its own pattern, and the legend
            // sample of a series carries the same pattern (and marker).
            let svg = fig.to_svg();
            let mut patterns = Vec::new();
            for (k, &col) in PALETTE[..n].iter().enumerate() {
                if marker != Marker::Points {
                    let paths = svg_elements(&svg, "<path", col);
                    assert_eq!(paths.len(), 1, "{what}: series {k}: {paths:?}");
                    let dash = attr(paths[0], "stroke-dasharray");
                    assert_eq!(dash.is_some(), k >= 3, "{what}: series {k}: {}", paths[0]);
                    let samples = svg_elements(&svg, "<line", col);
                    assert_eq!(samples.len(), 1, "{what}: legend sample of {k}");
                    assert_eq!(
                        attr(samples[0], "stroke-dasharray"),
                        dash,
                        "{what}: legend {k}"
                    );
                    assert_eq!(
                        attr(samples[0], "stroke-dashoffset"),
                        attr(paths[0], "stroke-dashoffset"),
                        "{what}: legend {k}"
                    );
                    patterns.extend(dash);
                    // The PNG legend sample shows gaps exactly when dashed.
                    let runs = (legend[1] as u32..legend[3] as u32)
                        .map(|y| {
                            let on: Vec<bool> = (legend[0] as u32..legend[2] as u32)
                                .map(|x| c.get(x, y) == col)
                                .collect();
                            on.windows(2).filter(|w| w[1] && !w[0]).count() + usize::from(on[0])
                        })
                        .max()
                        .unwrap_or(0);
                    if marker == Marker::LinePoints && k < 3 {
                        // The dot may split the sample's visible line; fine.
                        assert!(runs >= 1, "{what}: legend sample {k} missing");
                    } else {
                        assert_eq!(runs > 1, k >= 3, "{what}: legend sample {k}: {runs} runs");
                    }
                }
                if matches!(marker, Marker::Points | Marker::LinePoints) {
                    // Data markers (clipped) and the legend marker (not clipped)
                    // are drawn alike: same group style, same circle radius.
                    let groups = svg_elements(&svg, "<g", col);
                    assert_eq!(groups.len(), 2, "{what}: series {k}: {groups:?}");
                    let style = |g: &str| g.replace(" clip-path=\"url(#plotarea)\"", "");
                    assert_eq!(style(groups[0]), style(groups[1]), "{what}: {k}");
                }
            }
            let mut distinct = patterns.clone();
            distinct.sort_unstable();
            distinct.dedup();
            assert_eq!(distinct.len(), patterns.len(), "{what}: {patterns:?}");
        }
    }
    // Dashes are cut after clipping: wild values cost no endless dash loop.
    let mut fig = Figure::new("wild").y_range(-1.0, 1.0);
    for k in 0..4 {
        let y = [-1e300, 1e300, f64::MAX];
        fig.series(&format!("{k}"), &[0.0, 1.0, 2.0], &y, Marker::Line);
    }
    let (w, _, _) = parse_png(&fig.to_png()).expect("valid PNG");
    assert_eq!(w, 900);
}

#[test]
fn equal_aspect_draws_one_unit_as_many_pixels_along_both_axes() {
    // A unit square and its diagonal: with equal scales the diagonal is at 45 degrees.
    for (w, h) in [(900, 700), (500, 900)] {
        let mut fig = Figure::new("square").size(w, h).x_range(0.0, 2.0).y_range(0.0, 1.0).equal_aspect();
        fig.series("diagonal", &[0.0, 1.0], &[0.0, 1.0], Marker::Line);
        let lay = fig.layout();
        let (ux, uy) = ((lay.r - lay.l) / (lay.x.1 - lay.x.0), (lay.b - lay.t) / (lay.y.1 - lay.y.0));
        assert!((ux / uy - 1.0).abs() < 0.01, "{w}x{h}: {ux} px per unit along x, {uy} along y");
        // The data stay inside the widened ranges.
        assert!(lay.x.0 <= 0.0 && lay.x.1 >= 2.0 && lay.y.0 <= 0.0 && lay.y.1 >= 1.0, "{:?} {:?}", lay.x, lay.y);
    }
}

#[test]
fn a_cloud_is_small_grey_dots_under_later_series() {
    let mut fig = Figure::new("cloud");
    fig.series("cloud", &[0.0, 1.0], &[0.0, 1.0], Marker::Cloud);
    fig.series("line", &[0.0, 1.0], &[1.0, 0.0], Marker::Line);
    let (_, prims) = fig.scene();
    let dots: Vec<_> = prims.iter().filter_map(|p| if let Prim::Dots(_, c, r, _, true) = p { Some((*c, *r)) } else { None }).collect();
    assert_eq!(dots, [(GREY, CLOUD_R)]);
}

#[test]
fn a_long_title_is_wrapped_inside_the_image() {
    let title = "Pure P (sin pattern) from the position perturbations, step 9024 (some disks off scale, see the caption)";
    let mut fig = Figure::new(title).size(900, 600);
    fig.series("a", &[0.0, 1.0], &[0.0, 1.0], Marker::Line);
    let lines = fig.title_lines(2);
    assert!(lines.len() >= 2, "{lines:?}");
    assert_eq!(lines.join(" "), title, "every word kept, in order");
    assert!(lines.iter().all(|l| text_w(l, 2) <= 900.0 - 16.0), "{lines:?}");
    // The frame starts below the last line.
    let lay = fig.layout();
    assert!(lay.t >= (1.25 + 1.25 * lines.len() as f64) * 16.0 - 1.0, "top {}", lay.t);
    let short = Figure::new("short").title_lines(2);
    assert_eq!(short, ["short"]);
    // A word wider than the image is cut into pieces that fit, and a title of many lines
    // keeps four, the last marked as cut; every line is drawn inside the image, above the
    // frame.
    for (title, size) in [("x".repeat(160), (900, 700)), (["word"; 300].join(" "), (300, 300))] {
        let mut fig = Figure::new(&title).size(size.0, size.1);
        fig.series("a", &[0.0, 1.0], &[0.0, 1.0], Marker::Line);
        let lines = fig.title_lines(fig.layout().scale);
        assert!(lines.len() <= TITLE_LINES && lines.iter().all(|l| text_w(l, fig.layout().scale) <= size.0 as f64 - 16.0), "{lines:?}");
        let (lay, prims) = fig.scene();
        let ys: Vec<f64> = prims.iter().filter_map(|p| if let Prim::Text(l) = p { l.bold.then_some(l.y) } else { None }).collect();
        let ch = 8.0 * lay.scale as f64;
        assert!(ys.iter().all(|&y| y - ch / 2.0 >= 0.0 && y + ch / 2.0 < lay.t), "{ys:?} against the frame at {}", lay.t);
    }
    let long = Figure::new(&["word"; 300].join(" ")).size(300, 300).title_lines(1);
    assert!(long.last().unwrap().ends_with("..."), "{long:?}");
}

/// `color` gives a series the palette entry asked for, whatever its place; `open_markers`
/// makes its markers rings or dots, whatever its place, in the plot and in the legend, and
/// coinciding open and filled markers both stay visible.
#[test]
fn colours_and_open_or_filled_markers_are_set_per_series() {
    let xs: Vec<f64> = (0..12).map(f64::from).collect();
    let ys: Vec<f64> = xs.iter().map(|x| x * x).collect();
    let mut fig = Figure::new("styles");
    fig.series("a", &xs, &ys, Marker::Points).color(2);
    fig.series("b", &xs, &ys, Marker::Line).color(5);
    fig.series("c", &xs, &ys, Marker::Line);
    fig.series("d", &xs, &ys, Marker::Points).color(1).open_markers(false);
    fig.series("open", &xs, &ys, Marker::Points).color(0).open_markers(true);
    let pens = fig.pens();
    assert_eq!(fig.series[1].color, PALETTE[5]);
    // A reference curve is grey, whatever its place, and takes no palette colour.
    let mut bands = Figure::new("bands");
    bands.series("bound", &xs, &ys, Marker::Line).grey();
    assert!(bands.series[0].color == GREY && !PALETTE.contains(&bands.series[0].color));
    assert_eq!((fig.series[3].color, fig.series[4].color), (PALETTE[1], PALETTE[0]));
    // Dots by their place among the series set or left to draw dots (3, 2, then 1.5 px),
    // rings from 4.5 px on.
    assert_eq!(pens.iter().map(|p| (p.ring, p.dot_r)).collect::<Vec<_>>()[..], [(false, 3.0), (false, 2.0), (false, 1.5), (false, 1.5), (true, 4.5)][..]);
    // Without any set, pens are pen's.
    let mut plain = Figure::new("plain");
    for k in 0..6 {
        plain.series(&k.to_string(), &xs, &ys, Marker::Points);
    }
    for (k, p) in plain.pens().iter().enumerate() {
        let q = pen(k, 6);
        assert_eq!((p.ring, p.dot_r, p.widen, p.dash), (q.ring, q.dot_r, q.widen, q.dash), "series {k}");
    }
    // SVG: the open series' markers (plot and legend) are unfilled circles of one radius,
    // the filled one's filled.
    let svg = fig.to_svg();
    let groups = |col| svg_elements(&svg, "<g", col);
    let open = groups(PALETTE[0]);
    assert!(open.len() == 2 && open.iter().all(|g| attr(g, "fill") == Some("none")), "{open:?}");
    let filled = groups(PALETTE[1]);
    assert!(filled.len() == 2 && filled.iter().all(|g| attr(g, "fill") == Some("#d55e00")), "{filled:?}");
    // PNG: at a data point the ring leaves its centre to the dots beneath, and shows around them.
    let c = fig.raster();
    let lay = fig.layout();
    let (px, py) = lay.map((6.0, 36.0));
    let (x, y) = (px.round() as u32, py.round() as u32);
    assert_ne!(c.get(x, y), PALETTE[0], "an open marker's centre is not painted");
    assert!(colours_near(&c, (px, py), 5).contains(&PALETTE[0]), "ring missing");
    assert!(colours_near(&c, (px, py), 1).contains(&PALETTE[1]), "the dot under the ring is hidden");
}

/// Panels: every panel is its figure's own image, placed in a grid of the given columns
/// under the title; the SVG holds one translated group per panel with a clip path of its
/// own.
#[test]
fn panels_place_whole_figures_in_a_grid_under_a_title() {
    let panel = |k: usize| {
        let mut fig = Figure::new(&format!("panel {k}")).size(500, 400);
        let xs: Vec<f64> = (0..20).map(f64::from).collect();
        let ys: Vec<f64> = xs.iter().map(|x| (x / (k + 2) as f64).sin()).collect();
        fig.series("", &xs, &ys, Marker::Line).color(k);
        fig
    };
    let mut p = Panels::new("Three panels, two to a row", 2);
    for k in 0..3 {
        p.push(panel(k));
    }
    let (w, h, title, corners) = p.layout();
    let top = title_height(1, 16.0) as u32;
    assert_eq!((w, h), (1000, top + 800));
    assert_eq!(corners, [(0, top), (500, top), (0, top + 400)]);
    assert_eq!(title.len(), 1);
    let c = p.raster();
    for (k, &(x0, y0)) in corners.iter().enumerate() {
        let own = panel(k).raster();
        let same = (0..own.h).all(|y| (0..own.w).all(|x| c.get(x0 + x, y0 + y) == own.get(x, y)));
        assert!(same, "panel {k} is not its figure's image");
    }
    // The empty fourth cell stays white; the title is drawn above the panels.
    assert!((top..top + 400).all(|y| (500..1000).all(|x| c.get(x, y + 400) == WHITE)));
    assert!((0..top).any(|y| (0..w).any(|x| c.get(x, y).0 < 80)), "title missing");
    let (pw, ph, _) = parse_png(&p.to_png()).expect("valid PNG");
    assert_eq!((pw, ph), (w, h));
    let svg = p.to_svg();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert_eq!(svg.matches("<g transform=\"translate(").count(), 4, "the title's part and three panels");
    assert!(svg.contains("<g transform=\"translate(500.00 ") && svg.contains(&format!("translate(0.00 {}.00)", top + 400)));
    for k in 1..4 {
        assert!(svg.contains(&format!("<clipPath id=\"plotarea{k}\">")) && svg.contains(&format!("url(#plotarea{k})")), "panel {k}'s clip path");
    }
    assert_eq!(svg.matches("<g").count(), svg.matches("</g>").count());
    // One column stacks them.
    let mut stacked = Panels::new("", 1);
    stacked.push(panel(0)).push(panel(1));
    assert_eq!(stacked.layout().3, [(0, 0), (0, 400)]);
}

/// Sibling panels keep their legends in one inside corner where one is free in all of
/// them, and each panel alone still takes its own first free corner.
#[test]
fn panels_put_their_legends_in_one_corner() {
    let top_right = corner_figure(&[(0.97, 0.97)]);
    let free = sine_figure();
    assert_eq!(free.legend_corners(), Some([true, true, true, true]), "the sine figure's corners are all free");
    assert_eq!(top_right.legend_corners().map(|c| c[0]), Some(false));
    let mut p = Panels::new("", 2);
    p.push(free).push(corner_figure(&[(0.97, 0.97)]));
    let corner = p.legend_corner().expect("a corner free in both");
    assert_eq!(corner, 1, "top-left, the first free in both");
    let c = p.raster();
    let (_, _, _, corners) = p.layout();
    for (k, fig) in p.panels.iter().enumerate() {
        let lay = fig.layout_preferring(Some(corner));
        let bx = lay.legend.expect("legend");
        assert!(bx[0] == lay.l + 10.0 && bx[1] == lay.t + 10.0, "panel {k}'s legend not top-left: {bx:?}");
        let own = fig.raster_preferring(Some(corner));
        let (x0, y0) = corners[k];
        assert!((0..own.h).all(|y| (0..own.w).all(|x| c.get(x0 + x, y0 + y) == own.get(x, y))), "panel {k} drawn with the common corner");
    }
    // Alone, the free figure keeps the top-right corner.
    let lay = sine_figure().layout();
    assert_eq!(lay.legend.map(|b| b[2]), Some(lay.r - 10.0));
    // No corner free in both: each its own.
    let mut q = Panels::new("", 2);
    q.push(corner_figure(&[(0.97, 0.97), (0.03, 0.97)])).push(corner_figure(&[(0.97, 0.03), (0.03, 0.03)]));
    assert_eq!(q.legend_corner(), None);
}
