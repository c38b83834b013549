//! Frame sources: a folder of images, a y4m file, or a y4m stream on stdin, each read frame
//! by frame into one reused grey buffer.
//!
//! - **Folder**: every `*.png`, `*.jpg`, `*.jpeg` (any case) in it, sorted by file name
//!   (byte order, so name frames `frame-0001.png`, ... with leading zeros). Colour images are
//!   converted to grey with the Rec. 601 luma weights `(299 R + 587 G + 114 B) / 1000`.
//!   A file that cannot be read or decoded is a [`FrameError::Image`] for that frame; the
//!   next call goes on with the next file, and frame numbers keep counting the broken file so
//!   that they stay equal to the position in the sorted folder.
//! - **y4m** (YUV4MPEG2, [`crate::y4m`]): every colour space `ffmpeg` writes, 8 to 16 bits;
//!   the luma plane *is* the grey image (high bits of deeper samples). `-` reads the stream from stdin, so any video `ffmpeg`
//!   can decode works as a source:
//!   `ffmpeg -i video.mp4 -f yuv4mpegpipe -pix_fmt yuv420p - | formation-tracker track - ...`.
//!   The header's frame rate is reported by [`FrameSource::frame_rate`]. A stream that ends
//!   inside a frame (a truncated file, a killed pipe) ends cleanly: the partial frame is
//!   dropped and [`FrameSource::truncated`] says so; [`FrameSource::frames_read`] counts the
//!   complete frames. A malformed frame header cannot be resynchronised: it is one
//!   [`FrameError::Y4m`] and the stream ends.
//!
//! Frame sizes are limited to [`MAX_SIDE`] pixels a side (checked from the y4m header
//! before any buffer is allocated), so a corrupt header cannot ask for gigabytes.

use std::fs;
use std::io::{self, BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

/// Largest accepted image side, pixels.
pub const MAX_SIDE: usize = 16_384;

/// Errors of the frame sources. `Image` and `Y4m` concern one frame; the others one source.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// The input path does not exist or cannot be read.
    #[error("cannot open input {path}: {source}")]
    Open {
        /// The path given.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: io::Error,
    },
    /// A folder holds no PNG or JPEG file.
    #[error("folder {path} holds no .png, .jpg or .jpeg file")]
    EmptyFolder {
        /// The folder.
        path: PathBuf,
    },
    /// One image file could not be read or decoded (the folder source goes on; the file's
    /// time slot stays empty).
    #[error("{path}: {message} (skipped)")]
    Image {
        /// Position of the file in the sorted folder (its time slot).
        index: u64,
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The y4m stream header is not valid.
    #[error("not a usable y4m stream: {message}")]
    Y4mHeader {
        /// What went wrong.
        message: String,
    },
    /// A y4m frame could not be read (the stream ends here).
    #[error("y4m frame {index}: {message}; the stream ends here")]
    Y4m {
        /// Frame number.
        index: u64,
        /// What went wrong.
        message: String,
    },
    /// An image is larger than [`MAX_SIDE`] or empty.
    #[error("frame size {width}x{height} is outside 1..={max} pixels a side")]
    Size {
        /// Width.
        width: usize,
        /// Height.
        height: usize,
        /// The limit.
        max: usize,
    },
}

/// A grey image, row-major with stride equal to the width.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct GreyImage {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// `width * height` bytes.
    pub data: Vec<u8>,
}

impl GreyImage {
    /// Resizes the buffer (reusing its allocation) and returns the pixels.
    pub(crate) fn reshape(&mut self, width: usize, height: usize) -> &mut [u8] {
        self.width = width;
        self.height = height;
        self.data.resize(width * height, 0);
        &mut self.data
    }
}

/// One frame handed out by a [`FrameSource`]; the image borrows the source's buffer.
#[derive(Debug, Clone, Copy)]
pub struct Frame<'a> {
    /// Frame number from 0 (for a folder: position in the sorted list).
    pub index: u64,
    /// The image file the frame came from; `None` for a y4m stream (whose frames are
    /// named by `index`).
    pub file: Option<&'a Path>,
    /// The grey image.
    pub image: &'a GreyImage,
}

enum Kind {
    Folder {
        files: Vec<PathBuf>,
        next: usize,
    },
    Y4m {
        reader: Box<crate::y4m::Reader>,
        next: u64,
        done: bool,
    },
}

/// A sequence of grey frames from a folder, a y4m file or stdin.
pub struct FrameSource {
    kind: Kind,
    max_side: usize,
    grey: GreyImage,
    read: u64,
    truncated: bool,
}

impl std::fmt::Debug for FrameSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FrameSource")
            .field("frames_read", &self.read)
            .field("truncated", &self.truncated)
            .finish_non_exhaustive()
    }
}

fn is_image(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .is_some_and(|e| e == "png" || e == "jpg" || e == "jpeg")
}

impl FrameSource {
    /// Opens `input`: `-` for a y4m stream on stdin, a folder of images, or a y4m file.
    ///
    /// # Errors
    /// The path cannot be read, the folder has no images, or the y4m header is bad.
    pub fn open(input: &Path) -> Result<Self, FrameError> {
        Self::open_with_max_side(input, MAX_SIDE)
    }

    /// As [`FrameSource::open`], accepting frames of at most `max_side` pixels a side
    /// (instead of [`MAX_SIDE`]).
    ///
    /// # Errors
    /// As [`FrameSource::open`].
    pub fn open_with_max_side(input: &Path, max_side: usize) -> Result<Self, FrameError> {
        if input == Path::new("-") {
            return Self::y4m(Box::new(io::stdin().lock()), max_side);
        }
        let open_error = |source| FrameError::Open {
            path: input.to_path_buf(),
            source,
        };
        let meta = fs::metadata(input).map_err(open_error)?;
        if meta.is_dir() {
            return Self::folder(input, max_side);
        }
        let file = fs::File::open(input).map_err(open_error)?;
        Self::y4m(Box::new(file), max_side)
    }

    /// The images of a folder, sorted by name.
    ///
    /// # Errors
    /// The folder cannot be listed or has no images.
    pub fn from_folder(folder: &Path) -> Result<Self, FrameError> {
        Self::folder(folder, MAX_SIDE)
    }

    fn folder(folder: &Path, max_side: usize) -> Result<Self, FrameError> {
        let entries = fs::read_dir(folder).map_err(|source| FrameError::Open {
            path: folder.to_path_buf(),
            source,
        })?;
        let mut files: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| is_image(p) && !p.is_dir())
            .collect();
        if files.is_empty() {
            return Err(FrameError::EmptyFolder {
                path: folder.to_path_buf(),
            });
        }
        files.sort_by(|a, b| a.file_name().cmp(&b.file_name()));
        Ok(Self::new(Kind::Folder { files, next: 0 }, max_side))
    }

    /// A y4m stream from any reader (buffered here).
    ///
    /// # Errors
    /// [`FrameError::Y4mHeader`] for a missing or bad header or frames larger than
    /// [`MAX_SIDE`].
    pub fn from_y4m_reader(reader: Box<dyn Read>) -> Result<Self, FrameError> {
        Self::y4m(reader, MAX_SIDE)
    }

    fn y4m(reader: Box<dyn Read>, max_side: usize) -> Result<Self, FrameError> {
        let mut reader = BufReader::new(reader);
        let bad = |message: String| FrameError::Y4mHeader { message };
        let mut line = Vec::with_capacity(128);
        (&mut reader)
            .take(1024)
            .read_until(b'\n', &mut line)
            .map_err(|e| bad(e.to_string()))?;
        if line.last() != Some(&b'\n') {
            return Err(bad(if line.len() >= 1024 {
                "no end of header line within 1024 bytes: not a y4m stream".into()
            } else if line.starts_with(b"YUV4MPEG2") {
                "the stream ended inside its header".into()
            } else {
                "the stream does not start with YUV4MPEG2: not a y4m stream".into()
            }));
        }
        // The size is checked before any frame buffer is allocated.
        let header = crate::y4m::parse_header(&line).map_err(bad)?;
        let (width, height) = (header.width, header.height);
        if width == 0 || height == 0 || width > max_side || height > max_side {
            return Err(FrameError::Size {
                width,
                height,
                max: max_side,
            });
        }
        // The luma plane as read (deep samples two bytes) and its grey copy.
        let need = (width * height) as u64 * (header.colour.bytes_per_sample() as u64 + 1);
        if need > crate::limits::max_buffer() {
            return Err(bad(format!(
                "header field W/H: a {width}x{height} frame needs {} to read, more than the {} an input may take (a quarter of --max-memory)",
                crate::textfile::bytes_text(need),
                crate::textfile::bytes_text(crate::limits::max_buffer()),
            )));
        }
        Ok(Self::new(
            Kind::Y4m {
                reader: Box::new(crate::y4m::Reader::new(reader, header)),
                next: 0,
                done: false,
            },
            max_side,
        ))
    }

    fn new(kind: Kind, max_side: usize) -> Self {
        Self {
            kind,
            max_side,
            grey: GreyImage::default(),
            read: 0,
            truncated: false,
        }
    }

    /// The stream's frame rate (y4m header), frames per second.
    pub fn frame_rate(&self) -> Option<f64> {
        match &self.kind {
            Kind::Y4m { reader, .. } => reader
                .header()
                .rate
                .map(|(num, den)| num as f64 / den as f64),
            Kind::Folder { .. } => None,
        }
    }

    /// Number of frames, when known in advance (a folder).
    pub fn len_hint(&self) -> Option<u64> {
        match &self.kind {
            Kind::Folder { files, .. } => Some(files.len() as u64),
            Kind::Y4m { .. } => None,
        }
    }

    /// Frames read successfully so far.
    pub fn frames_read(&self) -> u64 {
        self.read
    }

    /// Whether a y4m stream ended inside a frame.
    pub fn truncated(&self) -> bool {
        self.truncated
    }

    /// The next frame; `Ok(None)` at the end.
    ///
    /// # Errors
    /// A broken frame: [`FrameError::Image`] (a folder; call again for the next file) or
    /// [`FrameError::Y4m`] (the stream then ends).
    pub fn next_frame(&mut self) -> Result<Option<Frame<'_>>, FrameError> {
        let (index, file) = match &mut self.kind {
            Kind::Folder { files, next } => {
                let Some(path) = files.get(*next) else {
                    return Ok(None);
                };
                let index = *next as u64;
                *next += 1;
                load_image(path, &mut self.grey, self.max_side).map_err(|message| {
                    FrameError::Image {
                        index,
                        path: path.clone(),
                        message,
                    }
                })?;
                (index, Some(path.as_path()))
            }
            Kind::Y4m { reader, next, done } => {
                if *done {
                    return Ok(None);
                }
                let index = *next;
                let (w, h) = (reader.header().width, reader.header().height);
                match reader.read_frame(self.grey.reshape(w, h)) {
                    Ok(crate::y4m::Next::Frame) => {
                        *next += 1;
                        (index, None)
                    }
                    Ok(crate::y4m::Next::End) => {
                        *done = true;
                        return Ok(None);
                    }
                    Ok(crate::y4m::Next::Truncated) => {
                        *done = true;
                        self.truncated = true;
                        return Ok(None);
                    }
                    Err(message) => {
                        *done = true;
                        return Err(FrameError::Y4m { index, message });
                    }
                }
            }
        };
        self.read += 1;
        Ok(Some(Frame {
            index,
            file,
            image: &self.grey,
        }))
    }
}

/// Reads an image file as 8-bit grey, the way every command does: the format is taken from
/// the file's content (not its extension), the size from its header before decoding (at
/// most [`MAX_SIDE`] a side), a JPEG that ends before its end-of-image marker is an error
/// (decoders would return a partly grey image), colour is converted with the BT.601
/// weights (alpha ignored), 16-bit samples are scaled to 8 bits, and the EXIF Orientation
/// tag (1-8) is applied, so the image is the one a viewer shows. Memory is linear in the
/// image size: the file's bytes, the decoded image and the grey buffer.
///
/// # Errors
/// One line saying why the file cannot be used.
pub fn read_grey(path: &Path) -> Result<GreyImage, String> {
    read_grey_with_max_side(path, MAX_SIDE)
}

/// As [`read_grey`], accepting images of at most `max_side` pixels a side.
///
/// # Errors
/// As [`read_grey`].
pub fn read_grey_with_max_side(path: &Path, max_side: usize) -> Result<GreyImage, String> {
    let mut grey = GreyImage {
        width: 0,
        height: 0,
        data: Vec::new(),
    };
    load_image(path, &mut grey, max_side)?;
    Ok(grey)
}

/// Whether a JPEG's last scan is followed by its end-of-image marker (`FF D9`). Entropy-coded
/// data escapes `FF` bytes, so the last `FF DA` (start of scan) is the real last scan, and a
/// complete file has an `FF D9` after it (thumbnails and their markers come earlier).
fn jpeg_is_complete(bytes: &[u8]) -> bool {
    let last_scan = bytes.windows(2).rposition(|w| w == [0xFF, 0xDA]);
    let last_end = bytes.windows(2).rposition(|w| w == [0xFF, 0xD9]);
    matches!((last_scan, last_end), (Some(s), Some(e)) if e > s)
}

/// Decodes an image file into the grey buffer (see [`read_grey`]).
fn load_image(path: &Path, grey: &mut GreyImage, max_side: usize) -> Result<(), String> {
    // An image file larger than the memory budget cannot be decoded within it either.
    let bytes = crate::textfile::read_bounded(path, crate::limits::max_buffer()).map_err(|e| {
        if e.kind() == std::io::ErrorKind::InvalidData {
            format!("too large for an image file: {e} (a quarter of --max-memory)")
        } else {
            e.to_string()
        }
    })?;
    decode_image(&bytes, grey, max_side)
}

/// Decodes the bytes of an image file (PNG, JPEG, or another format the `image` crate
/// reads) as 8-bit grey, exactly as [`read_grey`] does for a file: for a caller whose image
/// is already in memory (a message from a recording, a network buffer).
///
/// # Errors
/// As [`read_grey`].
pub fn decode_grey(bytes: &[u8], max_side: usize) -> Result<GreyImage, String> {
    let mut grey = GreyImage::default();
    decode_image(bytes, &mut grey, max_side)?;
    Ok(grey)
}

/// Decodes an encoded image (PNG, JPEG, ...) held in memory into the grey buffer, with the
/// checks of [`read_grey`] (shared by image files and compressed images in bags).
pub(crate) fn decode_image(
    bytes: &[u8],
    grey: &mut GreyImage,
    max_side: usize,
) -> Result<(), String> {
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| e.to_string())?;
    let format = reader.format().ok_or(
        "not an image format we read (the content is neither PNG nor JPEG nor another format \
         the `image` crate knows)",
    )?;
    // The header is read without the decoder's own limits, so that its size is reported
    // in our words; the limits are set before anything is decoded.
    reader.no_limits();
    // One decoder: the size from its header is checked before anything is decoded.
    let mut decoder = reader.into_decoder().map_err(|e| e.to_string())?;
    let (w, h) = image::ImageDecoder::dimensions(&decoder);
    check_decoded_size(w, h, image::ImageDecoder::total_bytes(&decoder), max_side)?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(max_side as u32);
    limits.max_image_height = Some(max_side as u32);
    limits.max_alloc = Some(crate::limits::max_buffer());
    image::ImageDecoder::set_limits(&mut decoder, limits).map_err(|e| e.to_string())?;
    if format == image::ImageFormat::Jpeg && !jpeg_is_complete(bytes) {
        return Err("truncated JPEG: the file ends before its end-of-image marker".into());
    }
    // The EXIF Orientation tag (1-8; JPEG APP1, PNG eXIf): cameras store the sensor's
    // rows and say how to turn them; the detector must see the picture as it is shown. An
    // unreadable tag is taken as "no rotation", as viewers do.
    let orientation = image::ImageDecoder::orientation(&mut decoder)
        .unwrap_or(image::metadata::Orientation::NoTransforms);
    let mut img = image::DynamicImage::from_decoder(decoder).map_err(|e| e.to_string())?;
    img.apply_orientation(orientation);
    let (w, h) = (img.width() as usize, img.height() as usize);
    let out = grey.reshape(w, h);
    let luma = bt601_luma;
    match &img {
        image::DynamicImage::ImageLuma8(g) => out.copy_from_slice(g.as_raw()),
        image::DynamicImage::ImageRgb8(c) => {
            for (o, p) in out.iter_mut().zip(c.as_raw().chunks_exact(3)) {
                *o = luma(p[0], p[1], p[2]);
            }
        }
        image::DynamicImage::ImageRgba8(c) => {
            for (o, p) in out.iter_mut().zip(c.as_raw().chunks_exact(4)) {
                *o = luma(p[0], p[1], p[2]);
            }
        }
        other => out.copy_from_slice(other.to_luma8().as_raw()),
    }
    Ok(())
}

/// Refuses, from its header, an image of `w` x `h` pixels that is empty, larger than
/// `max_side` a side, or whose decoded pixels (`decoded` bytes) and grey copy would not fit in
/// [`crate::limits::max_buffer`].
pub fn check_decoded_size(w: u32, h: u32, decoded: u64, max_side: usize) -> Result<(), String> {
    let (wu, hu) = (w as usize, h as usize);
    if wu == 0 || hu == 0 || wu > max_side || hu > max_side {
        return Err(format!(
            "image size {w}x{h} is outside 1..={max_side} pixels a side (--max-side sets the limit)"
        ));
    }
    let need = decoded.saturating_add(u64::from(w) * u64::from(h));
    let limit = crate::limits::max_buffer();
    if need > limit {
        return Err(format!(
            "image size {w}x{h} needs {} decoded, more than the {} an input may take (a quarter of --max-memory {})",
            crate::textfile::bytes_text(need),
            crate::textfile::bytes_text(limit),
            crate::textfile::bytes_text(crate::limits::max_memory()),
        ));
    }
    Ok(())
}

/// Grey from red, green and blue with the BT.601 weights, rounded: the one colour-to-grey
/// conversion of every frame source (image files, and colour images in bags).
pub(crate) fn bt601_luma(r: u8, g: u8, b: u8) -> u8 {
    ((299 * u32::from(r) + 587 * u32::from(g) + 114 * u32::from(b) + 500) / 1000) as u8
}
