//! y4m streams (`formation_io::y4m`): the header parser and the frame reader never
//! panic, an accepted header has a positive size and a positive finite frame rate, and at
//! most a few frames are read into a buffer of the header's size (streams larger than
//! 1024 x 1024 are only parsed, to keep each run short).

use std::io::{BufRead, BufReader, Read};

use formation_io::y4m::{Next, Reader, parse_header};

/// Reads `data` as a y4m stream.
pub fn run(data: &[u8]) {
    let mut inner = BufReader::new(Box::new(std::io::Cursor::new(data.to_vec())) as Box<dyn Read>);
    let mut line = Vec::new();
    if (&mut inner)
        .take(1024)
        .read_until(b'\n', &mut line)
        .is_err()
    {
        return;
    }
    let Ok(header) = parse_header(&line) else {
        return;
    };
    if let Some((num, den)) = header.rate {
        assert!(num > 0 && den > 0, "accepted a rate of {num}:{den}");
    }
    let (w, h) = (header.width, header.height);
    if w == 0 || h == 0 || w > 1024 || h > 1024 {
        return;
    }
    let mut luma = vec![0u8; w * h];
    let mut reader = Reader::new(inner, header);
    for _ in 0..4 {
        match reader.read_frame(&mut luma) {
            Ok(Next::Frame) => {}
            Ok(Next::End | Next::Truncated) | Err(_) => break,
        }
    }
}
