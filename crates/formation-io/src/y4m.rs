//! A YUV4MPEG2 (y4m) reader that keeps only the luma plane, for every colour space `ffmpeg
//! -f yuv4mpegpipe` writes.
//!
//! The stream is a header line, `YUV4MPEG2 W<width> H<height> [F<num>:<den>] [I<i>]
//! [A<num>:<den>] [C<colour>] [X<ext>]`, then frames, each a line starting with `FRAME` and
//! the planes: luma first, then chroma (and alpha) at the colour space's subsampling. The
//! colour space names the sample size too: `420jpeg`, `420paldv`, `420mpeg2`, `420`, `422`,
//! `444`, `411`, `444alpha` and `mono` are 8-bit; `420p10`, `422p12`, `444p16`, `mono10`,
//! `mono16`, ... (9 to 16 bits) store each sample in two little-endian bytes. The grey image
//! is the luma plane, high bits kept for deeper samples; the other planes are skipped.
//!
//! Errors name the header field and the value (`header field C: colour space \`nv12\` is not
//! one y4m defines`), and a stream that ends inside a frame is reported as truncated, not as
//! an error: the frames before it are good.

use std::io::{self, BufRead, BufReader, Read};

/// How the samples of a colour space are laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Colour {
    /// Bits per sample, 8 to 16 (two bytes per sample above 8).
    pub depth: u32,
    /// Horizontal and vertical chroma subsampling (1 = none); `None` for grey.
    pub chroma: Option<(usize, usize)>,
    /// A full-size alpha plane follows the chroma planes.
    pub alpha: bool,
}

impl Colour {
    /// The colour space of a `C` header field (without the `C`).
    ///
    /// # Errors
    /// A name y4m does not define, or a bit depth outside 8 to 16.
    pub fn parse(tag: &str) -> Result<Self, String> {
        let unknown = || format!("header field C: colour space `{tag}` is not one y4m defines");
        let (base, depth) = match tag.find('p').filter(|_| !tag.starts_with("mono")) {
            Some(i)
                if tag[..i].bytes().all(|b| b.is_ascii_digit())
                    && !tag[i + 1..].is_empty()
                    && tag[i + 1..].bytes().all(|b| b.is_ascii_digit()) =>
            {
                let depth = tag[i + 1..].parse::<u32>().map_err(|_| unknown())?;
                (&tag[..i], depth)
            }
            _ => match tag.strip_prefix("mono") {
                Some("") => ("mono", 8),
                Some(bits) => ("mono", bits.parse::<u32>().map_err(|_| unknown())?),
                None => (tag, 8),
            },
        };
        if !(8..=16).contains(&depth) {
            return Err(format!(
                "header field C: colour space `{tag}` has {depth}-bit samples; 8 to 16 are read"
            ));
        }
        let (chroma, alpha) = match base {
            "420" | "420jpeg" | "420paldv" | "420mpeg2" => (Some((2, 2)), false),
            "422" => (Some((2, 1)), false),
            "444" => (Some((1, 1)), false),
            "411" => (Some((4, 1)), false),
            "444alpha" => (Some((1, 1)), true),
            "mono" => (None, false),
            _ => return Err(unknown()),
        };
        Ok(Self {
            depth,
            chroma,
            alpha,
        })
    }

    /// Bytes per sample: 1 up to 8 bits, else 2.
    pub fn bytes_per_sample(&self) -> usize {
        if self.depth > 8 { 2 } else { 1 }
    }

    /// Bytes of the planes after the luma plane of a `width x height` frame.
    pub fn other_planes(&self, width: usize, height: usize) -> usize {
        let chroma = self
            .chroma
            .map_or(0, |(sx, sy)| 2 * width.div_ceil(sx) * height.div_ceil(sy));
        let alpha = if self.alpha { width * height } else { 0 };
        (chroma + alpha) * self.bytes_per_sample()
    }
}

/// The stream header.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Header {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Frame rate as `(numerator, denominator)` frames per second; `None` when absent or
    /// `0:0` (unknown).
    pub rate: Option<(u64, u64)>,
    /// The colour space (`420jpeg` when absent, as y4m says).
    pub colour: Colour,
}

/// Parses a header line (with or without its newline).
///
/// # Errors
/// The signature is missing, a field is malformed (named with its value), or `W` or `H`
/// is absent.
pub fn parse_header(line: &[u8]) -> Result<Header, String> {
    let line = line.strip_suffix(b"\n").unwrap_or(line);
    let text = std::str::from_utf8(line).map_err(|_| "the header is not text".to_string())?;
    let fields = text
        .strip_prefix("YUV4MPEG2")
        .ok_or("the stream does not start with YUV4MPEG2: not a y4m stream")?;
    let (mut width, mut height, mut rate) = (None, None, None);
    let mut colour = Colour::parse("420jpeg")?;
    for field in fields.split(' ').filter(|f| !f.is_empty()) {
        // The key is the field's first character, which need not be one byte long (a
        // corrupt header may hold any text): split after it, not after byte 1.
        let first = field.chars().next().map_or(0, char::len_utf8);
        let (key, value) = field.split_at(first);
        let number = |v: &str| {
            v.parse::<usize>()
                .map_err(|_| format!("header field {key}: `{v}` is not a whole number"))
        };
        match key {
            "W" => width = Some(number(value)?),
            "H" => height = Some(number(value)?),
            "F" => {
                let bad = || format!("header field F: `{value}` is not a frame rate num:den");
                let (n, d) = value.split_once(':').ok_or_else(bad)?;
                let (n, d) = (
                    n.parse::<u64>().map_err(|_| bad())?,
                    d.parse::<u64>().map_err(|_| bad())?,
                );
                rate = match (n, d) {
                    (0, 0) => None,
                    (_, 0) | (0, _) => return Err(bad()),
                    _ => Some((n, d)),
                };
            }
            "C" => colour = Colour::parse(value)?,
            // Interlacing, pixel aspect and extensions do not change the luma plane.
            "I" | "A" | "X" => {}
            _ => return Err(format!("header field `{field}` is not one y4m defines")),
        }
    }
    let width = width.ok_or("header field W (width) is missing")?;
    let height = height.ok_or("header field H (height) is missing")?;
    Ok(Header {
        width,
        height,
        rate,
        colour,
    })
}

/// What reading one frame gave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Next {
    /// A whole frame; its luma is in the buffer.
    Frame,
    /// The stream ended cleanly after the last frame.
    End,
    /// The stream ended inside a frame, which was dropped.
    Truncated,
}

/// Reads the frames of a stream whose header was already parsed.
pub struct Reader {
    inner: BufReader<Box<dyn Read>>,
    header: Header,
    /// Two-byte samples of a deep luma plane, before they are narrowed to 8 bits.
    wide: Vec<u8>,
}

impl std::fmt::Debug for Reader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Reader")
            .field("header", &self.header)
            .finish_non_exhaustive()
    }
}

impl Reader {
    /// A reader of `inner`, positioned after the header line.
    pub fn new(inner: BufReader<Box<dyn Read>>, header: Header) -> Self {
        Self {
            inner,
            header,
            wide: Vec::new(),
        }
    }

    /// The header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// Reads the next frame's luma plane into `luma` (`width * height` bytes, 8-bit).
    ///
    /// # Errors
    /// A frame header that is not `FRAME...` (the stream cannot be resynchronised), or an
    /// I/O error.
    pub fn read_frame(&mut self, luma: &mut [u8]) -> Result<Next, String> {
        let mut line = Vec::with_capacity(16);
        let n = (&mut self.inner)
            .take(1024)
            .read_until(b'\n', &mut line)
            .map_err(|e| e.to_string())?;
        if n == 0 {
            return Ok(Next::End);
        }
        if line.last() != Some(&b'\n') {
            return if line.len() < 1024 && b"FRAME".starts_with(&line[..line.len().min(5)]) {
                Ok(Next::Truncated)
            } else {
                Err(format!(
                    "frame header `{}` is not FRAME",
                    String::from_utf8_lossy(&line[..line.len().min(16)])
                ))
            };
        }
        if !line.starts_with(b"FRAME") {
            return Err(format!(
                "frame header `{}` is not FRAME",
                String::from_utf8_lossy(&line[..line.len().min(16)]).trim_end()
            ));
        }
        let Header {
            width,
            height,
            colour,
            ..
        } = self.header;
        let whole = if colour.bytes_per_sample() == 1 {
            read_full(&mut self.inner, &mut luma[..width * height])
        } else {
            self.wide.resize(2 * width * height, 0);
            read_full(&mut self.inner, &mut self.wide)
        };
        if !whole.map_err(|e| e.to_string())? {
            return Ok(Next::Truncated);
        }
        if colour.bytes_per_sample() == 2 {
            let shift = colour.depth - 8;
            for (o, s) in luma.iter_mut().zip(self.wide.chunks_exact(2)) {
                *o = (u16::from_le_bytes([s[0], s[1]]) >> shift).min(255) as u8;
            }
        }
        let rest = colour.other_planes(width, height) as u64;
        let skipped = io::copy(&mut (&mut self.inner).take(rest), &mut io::sink())
            .map_err(|e| e.to_string())?;
        Ok(if skipped == rest {
            Next::Frame
        } else {
            Next::Truncated
        })
    }
}

/// Fills `buf`; `Ok(false)` if the stream ended first.
fn read_full(r: &mut impl Read, buf: &mut [u8]) -> io::Result<bool> {
    let mut filled = 0;
    while filled < buf.len() {
        match r.read(&mut buf[filled..]) {
            Ok(0) => return Ok(false),
            Ok(n) => filled += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(true)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)] // tests may unwrap (house rules)
    use super::*;

    #[test]
    fn every_ffmpeg_colour_space_has_a_layout() {
        for (tag, depth, other) in [
            ("420jpeg", 8, 2 * 2 * 2),
            ("420mpeg2", 8, 8),
            ("420paldv", 8, 8),
            ("420", 8, 8),
            ("422", 8, 2 * 2 * 4),
            ("444", 8, 2 * 16),
            ("411", 8, 2 * 4),
            ("444alpha", 8, 3 * 16),
            ("mono", 8, 0),
            ("mono10", 10, 0),
            ("mono16", 16, 0),
            ("420p10", 10, 2 * 8),
            ("422p12", 12, 2 * 16),
            ("444p16", 16, 2 * 32),
            ("420p9", 9, 2 * 8),
        ] {
            let c = Colour::parse(tag).unwrap();
            assert_eq!(c.depth, depth, "{tag}");
            assert_eq!(c.other_planes(4, 4), other, "{tag}");
        }
        for bad in ["nv12", "420p7", "mono17", "444p", "C"] {
            let e = Colour::parse(bad).unwrap_err();
            assert!(e.contains(bad) && e.starts_with("header field C"), "{e}");
        }
    }

    /// Found by the y4m fuzz target: a field starting with a multi-byte character split
    /// inside it and panicked.
    #[test]
    fn a_field_starting_with_a_multibyte_character_is_an_error_not_a_panic() {
        for line in [
            "YUV4MPEG2 W4 H2 \u{6b9}30:1".as_bytes(),
            "YUV4MPEG2 W4 H2 F30:1 \u{1d2}onoJF".as_bytes(),
            b"YUV4MPEG2\xda\xb93\x100:",
        ] {
            assert!(parse_header(line).is_err(), "{line:?}");
        }
        let e = parse_header("YUV4MPEG2 W4 H2 \u{6b9}30:1".as_bytes()).unwrap_err();
        assert!(e.contains('\u{6b9}'), "{e}");
    }

    #[test]
    fn header_fields_are_named_in_errors() {
        let h = parse_header(b"YUV4MPEG2 W640 H480 F30000:1001 Ip A1:1 C420p10 XYSCSS=420P10\n")
            .unwrap();
        assert_eq!((h.width, h.height, h.rate), (640, 480, Some((30000, 1001))));
        assert_eq!(h.colour.depth, 10);
        assert_eq!(parse_header(b"YUV4MPEG2 W2 H2 F0:0").unwrap().rate, None);
        for (line, says) in [
            (&b"P5 640 480"[..], "not a y4m stream"),
            (b"YUV4MPEG2 W640", "H (height) is missing"),
            (
                b"YUV4MPEG2 Wabc H4",
                "header field W: `abc` is not a whole number",
            ),
            (b"YUV4MPEG2 W4 H4 F30", "header field F: `30`"),
            (b"YUV4MPEG2 W4 H4 F30:0", "header field F: `30:0`"),
            (b"YUV4MPEG2 W4 H4 Q1", "`Q1` is not one y4m defines"),
        ] {
            let e = parse_header(line).unwrap_err();
            assert!(e.contains(says), "{e}");
        }
    }
}
