//! Little-endian fields read in order from a byte slice: the one reader of
//! the tile codec's header, the wire messages and snowpack's saved window
//! state. Each read names its field, so running out of bytes is an error
//! that says what was being read; each format turns it into its own error
//! (a corrupt file, a truncated message).

/// Bytes ran out: the field being read, the bytes it needed and those left.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Truncated {
    /// The field, as the format names it ("protocol version", "tile count").
    pub what: &'static str,
    /// Bytes the field needed.
    pub needed: usize,
    /// Bytes that were left.
    pub left: usize,
}

impl std::fmt::Display for Truncated {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "truncated at {}: {} bytes needed, {} left", self.what, self.needed, self.left)
    }
}

/// A cursor over a byte slice that reads little-endian fields in order.
#[derive(Clone, Debug)]
pub struct ByteReader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> ByteReader<'a> {
    /// A reader at the start of `bytes`.
    #[must_use]
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, at: 0 }
    }

    /// Bytes not read yet.
    #[must_use]
    pub fn left(&self) -> usize {
        self.bytes.len() - self.at
    }

    /// Whether `n` more bytes are there, without reading them: checked
    /// before allocating for a count read from the bytes themselves.
    pub fn need(&self, n: usize, what: &'static str) -> Result<(), Truncated> {
        let left = self.left();
        if n > left { Err(Truncated { what, needed: n, left }) } else { Ok(()) }
    }

    /// The next `n` bytes as they are.
    pub fn take(&mut self, n: usize, what: &'static str) -> Result<&'a [u8], Truncated> {
        self.need(n, what)?;
        let out = &self.bytes[self.at..self.at + n];
        self.at += n;
        Ok(out)
    }

    /// The next `N` bytes as an array.
    pub fn array<const N: usize>(&mut self, what: &'static str) -> Result<[u8; N], Truncated> {
        let mut out = [0; N];
        out.copy_from_slice(self.take(N, what)?);
        Ok(out)
    }

    /// A byte.
    pub fn u8(&mut self, what: &'static str) -> Result<u8, Truncated> {
        Ok(self.array::<1>(what)?[0])
    }

    /// A little-endian `u16`.
    pub fn u16(&mut self, what: &'static str) -> Result<u16, Truncated> {
        Ok(u16::from_le_bytes(self.array(what)?))
    }

    /// A little-endian `u32`.
    pub fn u32(&mut self, what: &'static str) -> Result<u32, Truncated> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }

    /// A little-endian `u64`.
    pub fn u64(&mut self, what: &'static str) -> Result<u64, Truncated> {
        Ok(u64::from_le_bytes(self.array(what)?))
    }

    /// A little-endian `i64`.
    pub fn i64(&mut self, what: &'static str) -> Result<i64, Truncated> {
        Ok(i64::from_le_bytes(self.array(what)?))
    }

    /// A little-endian `f32`.
    pub fn f32(&mut self, what: &'static str) -> Result<f32, Truncated> {
        Ok(f32::from_le_bytes(self.array(what)?))
    }

    /// A little-endian `f64`.
    pub fn f64(&mut self, what: &'static str) -> Result<f64, Truncated> {
        Ok(f64::from_le_bytes(self.array(what)?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_in_order_and_what_ran_out() {
        let mut bytes = vec![7u8];
        bytes.extend_from_slice(&0x1234u16.to_le_bytes());
        bytes.extend_from_slice(&(-5i64).to_le_bytes());
        bytes.extend_from_slice(&1.5f32.to_le_bytes());
        bytes.extend_from_slice(&[1, 2]);
        let mut r = ByteReader::new(&bytes);
        assert_eq!(r.u8("a"), Ok(7));
        assert_eq!(r.u16("b"), Ok(0x1234));
        assert_eq!(r.i64("c"), Ok(-5));
        assert_eq!(r.f32("d"), Ok(1.5));
        assert_eq!(r.left(), 2);
        assert_eq!(r.u32("e"), Err(Truncated { what: "e", needed: 4, left: 2 }));
        // A failed read takes nothing: what is left can still be read.
        assert_eq!(r.take(2, "f"), Ok(&[1u8, 2][..]));
        assert_eq!(r.left(), 0);
        assert_eq!(r.u8("g").unwrap_err().to_string(), "truncated at g: 1 bytes needed, 0 left");
    }
}
