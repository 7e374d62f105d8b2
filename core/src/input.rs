//! Opening input files that may be gzip-compressed: one detection, by the gzip magic bytes
//! (`1f 8b`) whatever the file's name, shared by every reader of campaigns and recordings.
//!
//! A gzip file is decompressed as it is read (all members, as `gzip -d` does), so readers see
//! text and count lines in it; a corrupt or truncated stream is a read error that says so.

use std::fs::File;
use std::io::{self, BufRead, BufReader, Chain, Cursor, Read};
use std::path::Path;

use flate2::read::MultiGzDecoder;

/// The first two bytes of every gzip file (RFC 1952, section 2.3.1).
pub const GZIP_MAGIC: [u8; 2] = [0x1f, 0x8b];

/// The file with the bytes read to look for the magic put back in front.
type Head = Chain<Cursor<Vec<u8>>, File>;

/// An opened input file: its text, decompressed when the file is gzip.
pub enum Input {
    /// A plain file.
    Plain(BufReader<Head>),
    /// A gzip file, decompressed as it is read.
    Gzip(BufReader<MultiGzDecoder<Head>>),
}

impl Input {
    /// Opens `path`, decompressing it when it starts with [`GZIP_MAGIC`].
    pub fn open(path: &Path) -> io::Result<Input> {
        let mut f = File::open(path)?;
        let mut magic = [0u8; 2];
        let mut got = 0;
        while got < magic.len() {
            match f.read(&mut magic[got..]) {
                Ok(0) => break,
                Ok(n) => got += n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        let head = Cursor::new(magic[..got].to_vec()).chain(f);
        Ok(if magic[..got] == GZIP_MAGIC {
            Input::Gzip(BufReader::new(MultiGzDecoder::new(head)))
        } else {
            Input::Plain(BufReader::new(head))
        })
    }

    /// Whether the file is gzip-compressed.
    pub fn is_gzip(&self) -> bool {
        matches!(self, Input::Gzip(_))
    }
}

/// Says that an error of the decompressor comes from the gzip stream (flate2's messages, such
/// as "corrupt deflate stream", do not name gzip; a truncated stream ends in an unexpected EOF).
fn gzip_error(e: io::Error) -> io::Error {
    if e.kind() == io::ErrorKind::Interrupted {
        return e;
    }
    let what = if e.kind() == io::ErrorKind::UnexpectedEof { "truncated" } else { "corrupt" };
    io::Error::new(e.kind(), format!("{what} gzip stream: {e}"))
}

impl Read for Input {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        match self {
            Input::Plain(r) => r.read(buf),
            Input::Gzip(r) => r.read(buf).map_err(gzip_error),
        }
    }
}

impl BufRead for Input {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        match self {
            Input::Plain(r) => r.fill_buf(),
            Input::Gzip(r) => r.fill_buf().map_err(gzip_error),
        }
    }

    fn consume(&mut self, amt: usize) {
        match self {
            Input::Plain(r) => r.consume(amt),
            Input::Gzip(r) => r.consume(amt),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn gzip(bytes: &[u8]) -> Vec<u8> {
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        enc.write_all(bytes).unwrap();
        enc.finish().unwrap()
    }

    fn read_all(path: &Path) -> io::Result<(bool, String)> {
        let mut input = Input::open(path)?;
        let mut s = String::new();
        input.read_to_string(&mut s)?;
        Ok((input.is_gzip(), s))
    }

    #[test]
    fn gzip_is_told_by_its_magic_not_its_name() {
        let dir = tempfile::tempdir().unwrap();
        let text = "t_s,x\n0,1\n";
        let (plain, gz, short) = (dir.path().join("a.gz"), dir.path().join("a.csv"), dir.path().join("one"));
        std::fs::write(&plain, text).unwrap();
        std::fs::write(&gz, gzip(text.as_bytes())).unwrap();
        std::fs::write(&short, [0x1f]).unwrap();
        assert_eq!(read_all(&plain).unwrap(), (false, text.to_string()));
        assert_eq!(read_all(&gz).unwrap(), (true, text.to_string()));
        assert_eq!(read_all(&short).unwrap(), (false, "\u{1f}".to_string()));
        let mut two = gzip(b"a\n");
        two.extend(gzip(b"b\n"));
        std::fs::write(&gz, two).unwrap();
        assert_eq!(read_all(&gz).unwrap().1, "a\nb\n");
    }

    #[test]
    fn a_truncated_or_corrupt_stream_is_an_error_that_names_gzip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.csv");
        let full = gzip("t_s,alpha_deg,beta_deg,x\n0,0,0,100\n".repeat(50).as_bytes());
        std::fs::write(&p, &full[..full.len() / 2]).unwrap();
        let e = read_all(&p).unwrap_err().to_string();
        assert!(e.starts_with("truncated gzip stream"), "{e}");
        std::fs::write(&p, [0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 0, 1, 2, 3, 4]).unwrap();
        let e = read_all(&p).unwrap_err().to_string();
        assert!(e.contains("gzip stream"), "{e}");
    }
}
