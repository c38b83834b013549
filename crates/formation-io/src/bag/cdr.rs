//! ROS 2 CDR (XCDR1): the message types `track` reads from a bag, and the one it writes
//! (`sensor_msgs/msg/Image`).
//!
//! A payload is a 4-byte encapsulation header (`00 01` little endian, `00 00` big endian,
//! then two option bytes) followed by the fields; each primitive is aligned to its own size
//! counted from the end of the header. Strings are a `u32` length (with the terminating
//! NUL) and the bytes; sequences a `u32` count and the elements. Every length is checked
//! against the bytes that remain before anything is allocated, so a corrupted length is an
//! error, never a huge allocation.

/// A CDR read that went wrong: what, and at which byte of the payload.
pub type CdrError = String;

/// A bounds-checked CDR reader.
#[derive(Debug)]
pub struct CdrReader<'a> {
    bytes: &'a [u8],
    pos: usize,
    little: bool,
}

impl<'a> CdrReader<'a> {
    /// A reader over `payload`, after checking its encapsulation header.
    ///
    /// # Errors
    /// The payload is shorter than its header or the header is not plain CDR.
    pub fn new(payload: &'a [u8]) -> Result<Self, CdrError> {
        if payload.len() < 4 {
            return Err(format!(
                "{} bytes, shorter than the 4-byte CDR header",
                payload.len()
            ));
        }
        let little = match (payload[0], payload[1]) {
            (0, 1) => true,
            (0, 0) => false,
            (a, b) => {
                return Err(format!(
                    "encapsulation {a:02x} {b:02x} is not plain CDR (00 00 or 00 01)"
                ));
            }
        };
        Ok(Self {
            bytes: &payload[4..],
            pos: 0,
            little,
        })
    }

    fn align(&mut self, n: usize) {
        let rem = self.pos % n;
        if rem != 0 {
            self.pos += n - rem;
        }
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], CdrError> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|e| *e <= self.bytes.len())
            .ok_or_else(|| {
                format!(
                    "needs {n} bytes at byte {} of a {}-byte message",
                    self.pos + 4,
                    self.bytes.len() + 4
                )
            })?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    fn fixed<const N: usize>(&mut self) -> Result<[u8; N], CdrError> {
        self.align(N);
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N)?);
        if !self.little {
            a.reverse();
        }
        Ok(a)
    }

    /// A `uint8` or `bool`.
    pub fn u8(&mut self) -> Result<u8, CdrError> {
        Ok(self.take(1)?[0])
    }
    /// A `uint32`.
    pub fn u32(&mut self) -> Result<u32, CdrError> {
        Ok(u32::from_le_bytes(self.fixed::<4>()?))
    }
    /// An `int32`.
    pub fn i32(&mut self) -> Result<i32, CdrError> {
        Ok(i32::from_le_bytes(self.fixed::<4>()?))
    }
    /// A `float64`.
    pub fn f64(&mut self) -> Result<f64, CdrError> {
        Ok(f64::from_le_bytes(self.fixed::<8>()?))
    }

    /// A length prefix, checked against the bytes left for elements of `size` bytes.
    fn length(&mut self, size: usize) -> Result<usize, CdrError> {
        let n = self.u32()? as usize;
        let left = self.bytes.len() - self.pos.min(self.bytes.len());
        if n.saturating_mul(size) > left {
            return Err(format!(
                "a length of {n} at byte {} runs past the end of the message ({left} bytes left)",
                self.pos + 4
            ));
        }
        Ok(n)
    }

    /// A `string`.
    pub fn string(&mut self) -> Result<String, CdrError> {
        let n = self.length(1)?;
        let b = self.take(n)?;
        let b = b.strip_suffix(&[0]).unwrap_or(b);
        String::from_utf8(b.to_vec()).map_err(|_| "a string is not UTF-8".to_owned())
    }

    /// A `uint8[]` (borrowed).
    pub fn bytes(&mut self) -> Result<&'a [u8], CdrError> {
        let n = self.length(1)?;
        self.take(n)
    }

    /// A `float64[]`.
    pub fn f64_seq(&mut self) -> Result<Vec<f64>, CdrError> {
        let n = self.length(8)?;
        (0..n).map(|_| self.f64()).collect()
    }

    /// A `float64[N]`.
    pub fn f64_array<const N: usize>(&mut self) -> Result<[f64; N], CdrError> {
        let mut a = [0.0; N];
        for v in &mut a {
            *v = self.f64()?;
        }
        Ok(a)
    }

    /// A `std_msgs/Header`'s stamp (nanoseconds since the epoch; negative seconds are
    /// refused) and frame id.
    pub fn header(&mut self) -> Result<(u64, String), CdrError> {
        let sec = self.i32()?;
        let nsec = self.u32()?;
        let frame_id = self.string()?;
        if sec < 0 || nsec >= 1_000_000_000 {
            return Err(format!(
                "header.stamp {sec} s {nsec} ns is not a valid time"
            ));
        }
        Ok((sec as u64 * 1_000_000_000 + u64::from(nsec), frame_id))
    }
}

/// `sensor_msgs/msg/Image`, the pixels borrowed.
#[derive(Debug, Clone)]
pub struct Image<'a> {
    /// `header.stamp`, nanoseconds.
    pub stamp_ns: u64,
    /// `header.frame_id`.
    pub frame_id: String,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Pixel encoding (`mono8`, `rgb8`, ...).
    pub encoding: String,
    /// Whether multi-byte samples are big endian.
    pub is_bigendian: bool,
    /// Bytes per row.
    pub step: u32,
    /// The pixels.
    pub data: &'a [u8],
}

impl<'a> Image<'a> {
    /// Parses a CDR payload.
    ///
    /// # Errors
    /// A payload that is not this type.
    pub fn parse(payload: &'a [u8]) -> Result<Self, CdrError> {
        let mut r = CdrReader::new(payload)?;
        let (stamp_ns, frame_id) = r.header()?;
        Ok(Self {
            stamp_ns,
            frame_id,
            height: r.u32()?,
            width: r.u32()?,
            encoding: r.string()?,
            is_bigendian: r.u8()? != 0,
            step: r.u32()?,
            data: r.bytes()?,
        })
    }
}

/// `sensor_msgs/msg/CompressedImage`, the bytes borrowed.
#[derive(Debug, Clone)]
pub struct CompressedImage<'a> {
    /// `header.stamp`, nanoseconds.
    pub stamp_ns: u64,
    /// `format` (`jpeg`, `png`, `rgb8; jpeg compressed bgr8`, ...).
    pub format: String,
    /// The compressed image.
    pub data: &'a [u8],
}

impl<'a> CompressedImage<'a> {
    /// Parses a CDR payload.
    ///
    /// # Errors
    /// A payload that is not this type.
    pub fn parse(payload: &'a [u8]) -> Result<Self, CdrError> {
        let mut r = CdrReader::new(payload)?;
        let (stamp_ns, _) = r.header()?;
        Ok(Self {
            stamp_ns,
            format: r.string()?,
            data: r.bytes()?,
        })
    }
}

/// `sensor_msgs/msg/CameraInfo` (the fields a calibration needs).
#[derive(Debug, Clone, PartialEq)]
pub struct CameraInfo {
    /// `header.stamp`, nanoseconds.
    pub stamp_ns: u64,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// `plumb_bob`, `rational_polynomial`, `equidistant`, ...
    pub distortion_model: String,
    /// Distortion coefficients.
    pub d: Vec<f64>,
    /// Camera matrix, row-major.
    pub k: [f64; 9],
}

impl CameraInfo {
    /// Parses a CDR payload.
    ///
    /// # Errors
    /// A payload that is not this type.
    pub fn parse(payload: &[u8]) -> Result<Self, CdrError> {
        let mut r = CdrReader::new(payload)?;
        let (stamp_ns, _) = r.header()?;
        let height = r.u32()?;
        let width = r.u32()?;
        let distortion_model = r.string()?;
        let d = r.f64_seq()?;
        let k = r.f64_array::<9>()?;
        let _r = r.f64_array::<9>()?;
        let _p = r.f64_array::<12>()?;
        Ok(Self {
            stamp_ns,
            height,
            width,
            distortion_model,
            d,
            k,
        })
    }
}

/// The follower's own inputs from one message: `(v2, w2)` and the stamp, if the type has
/// one (`geometry_msgs/msg/Twist` has none).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwistSample {
    /// `header.stamp`, nanoseconds; `None` for a bare `Twist`.
    pub stamp_ns: Option<u64>,
    /// Linear velocity along the body's x, m/s.
    pub v: f64,
    /// Angular velocity about the body's z, rad/s.
    pub w: f64,
}

/// A `geometry_msgs/Twist`: linear (x, y, z) then angular (x, y, z); returns `(x, z)`.
fn twist(r: &mut CdrReader<'_>) -> Result<(f64, f64), CdrError> {
    let lin = r.f64_array::<3>()?;
    let ang = r.f64_array::<3>()?;
    Ok((lin[0], ang[2]))
}

/// The message types that carry the follower's inputs.
pub const TWIST_TYPES: [&str; 3] = [
    "nav_msgs/msg/Odometry",
    "geometry_msgs/msg/TwistStamped",
    "geometry_msgs/msg/Twist",
];

impl TwistSample {
    /// Parses a CDR payload of type `type_name` (one of [`TWIST_TYPES`]).
    ///
    /// # Errors
    /// Another type, or a payload that is not this type.
    pub fn parse(type_name: &str, payload: &[u8]) -> Result<Self, CdrError> {
        let mut r = CdrReader::new(payload)?;
        let (stamp_ns, (v, w)) = match type_name {
            "nav_msgs/msg/Odometry" => {
                let (stamp, _) = r.header()?;
                let _child = r.string()?;
                let _pose = r.f64_array::<7>()?;
                let _pose_cov = r.f64_array::<36>()?;
                (Some(stamp), twist(&mut r)?)
            }
            "geometry_msgs/msg/TwistStamped" => {
                let (stamp, _) = r.header()?;
                (Some(stamp), twist(&mut r)?)
            }
            "geometry_msgs/msg/Twist" => (None, twist(&mut r)?),
            other => {
                return Err(format!(
                    "{other} carries no follower inputs (expected one of {})",
                    TWIST_TYPES.join(", ")
                ));
            }
        };
        Self::checked(stamp_ns, v, w)
    }

    /// A sample of `v` (`twist.linear.x`, m/s) and `w` (`twist.angular.z`, rad/s), checked
    /// as every reader of follower inputs checks them (a recorded bag or a live topic).
    ///
    /// # Errors
    /// A value that is not finite, or outside a follower's speed and turn-rate range.
    pub fn checked(stamp_ns: Option<u64>, v: f64, w: f64) -> Result<Self, CdrError> {
        if !v.is_finite() || !w.is_finite() {
            return Err(format!(
                "twist.linear.x = {v} m/s, twist.angular.z = {w} rad/s: not finite"
            ));
        }
        use crate::inputs::{MAX_SPEED, MAX_TURN_RATE};
        if v.abs() > MAX_SPEED || w.abs() > MAX_TURN_RATE {
            return Err(format!(
                "twist.linear.x = {v:?} m/s, twist.angular.z = {w:?} rad/s: outside +-{MAX_SPEED} m/s, +-{MAX_TURN_RATE} rad/s for a follower"
            ));
        }
        Ok(Self { stamp_ns, v, w })
    }
}

/// CDR writer (little endian) for the messages we write.
#[derive(Debug, Default)]
pub struct CdrWriter {
    buf: Vec<u8>,
}

impl CdrWriter {
    /// A payload with its little-endian encapsulation header.
    pub fn new() -> Self {
        Self {
            buf: vec![0, 1, 0, 0],
        }
    }
    fn align(&mut self, n: usize) {
        while !(self.buf.len() - 4).is_multiple_of(n) {
            self.buf.push(0);
        }
    }
    /// A `uint8`.
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }
    /// A `uint32`.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// An `int32`.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// A `float64`.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// A `string`.
    pub fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }
    /// A `uint8[]`.
    pub fn bytes(&mut self, b: &[u8]) {
        self.u32(b.len() as u32);
        self.buf.extend_from_slice(b);
    }
    /// A `std_msgs/Header`.
    pub fn header(&mut self, stamp_ns: u64, frame_id: &str) {
        self.i32((stamp_ns / 1_000_000_000) as i32);
        self.u32((stamp_ns % 1_000_000_000) as u32);
        self.string(frame_id);
    }
    /// The payload.
    pub fn finish(self) -> Vec<u8> {
        self.buf
    }
}

/// A `sensor_msgs/msg/Image` payload of a grey (`mono8`) image.
pub fn mono8_image(stamp_ns: u64, frame_id: &str, width: u32, height: u32, data: &[u8]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    w.header(stamp_ns, frame_id);
    w.u32(height);
    w.u32(width);
    w.string("mono8");
    w.u8(0);
    w.u32(width);
    w.bytes(data);
    w.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_written_image_parses_back() {
        let p = mono8_image(1_700_000_000_123_456_789, "cam", 3, 2, &[1, 2, 3, 4, 5, 6]);
        let img = Image::parse(&p).unwrap();
        assert_eq!(img.stamp_ns, 1_700_000_000_123_456_789);
        assert_eq!(img.frame_id, "cam");
        assert_eq!((img.width, img.height, img.step), (3, 2, 3));
        assert_eq!(img.encoding, "mono8");
        assert_eq!(img.data, &[1, 2, 3, 4, 5, 6]);
    }

    #[test]
    fn big_endian_payloads_read_the_same() {
        // TwistStamped, big endian: stamp 7 s 9 ns, frame "", twist (0.5, 0, 0), (0, 0, -0.25).
        let mut p = vec![0u8, 0, 0, 0];
        p.extend_from_slice(&7i32.to_be_bytes());
        p.extend_from_slice(&9u32.to_be_bytes());
        p.extend_from_slice(&1u32.to_be_bytes());
        p.push(0);
        p.extend_from_slice(&[0; 3]); // align to 8 (offset 13 -> 16 after the header)
        for v in [0.5f64, 0.0, 0.0, 0.0, 0.0, -0.25] {
            p.extend_from_slice(&v.to_be_bytes());
        }
        let s = TwistSample::parse("geometry_msgs/msg/TwistStamped", &p).unwrap();
        assert_eq!(s.stamp_ns, Some(7_000_000_009));
        assert_eq!((s.v, s.w), (0.5, -0.25));
    }

    #[test]
    fn a_length_beyond_the_payload_is_an_error_not_an_allocation() {
        let mut w = CdrWriter::new();
        w.header(0, "");
        w.u32(1);
        w.u32(1);
        w.string("mono8");
        w.u8(0);
        w.u32(1);
        w.u32(u32::MAX); // data length
        let e = Image::parse(&w.finish()).unwrap_err();
        assert!(e.contains("runs past the end of the message"), "{e}");
        let e = CameraInfo::parse(&[0, 1, 0, 0, 1]).unwrap_err();
        assert!(e.contains("needs 4 bytes"), "{e}");
        let e = Image::parse(&[0, 7, 0, 0]).unwrap_err();
        assert!(e.contains("not plain CDR"), "{e}");
    }

    #[test]
    fn non_finite_velocities_and_negative_stamps_are_refused() {
        let mut w = CdrWriter::new();
        for v in [f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0] {
            w.f64(v);
        }
        let e = TwistSample::parse("geometry_msgs/msg/Twist", &w.finish()).unwrap_err();
        assert!(e.contains("not finite"), "{e}");
        // Finite but no follower's (#32: v = 1e300 reset the track every other frame).
        for (v, wz) in [(1e300, 0.0), (25.0, 0.0), (0.0, -21.0)] {
            let mut w = CdrWriter::new();
            for x in [v, 0.0, 0.0, 0.0, 0.0, wz] {
                w.f64(x);
            }
            let e = TwistSample::parse("geometry_msgs/msg/Twist", &w.finish()).unwrap_err();
            assert!(
                e.contains("outside +-20 m/s, +-20 rad/s") && e.contains("twist.linear.x"),
                "{e}"
            );
        }
        let mut w = CdrWriter::new();
        w.i32(-1);
        w.u32(0);
        w.string("");
        let e = TwistSample::parse("geometry_msgs/msg/TwistStamped", &w.finish()).unwrap_err();
        assert!(e.contains("not a valid time"), "{e}");
    }
}
