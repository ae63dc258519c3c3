//! A run of one X plane's sample bytes moving between neighbours (load balancing),
//! [`PlaneChunk`], and its encoding.
//!
//! Invariant: decoding refuses a used length past [`PLANE_CHUNK`].

use super::wire::{DecodeError, Reader, Writer};
use crate::node::kind::PLANE_CHUNK;

/// A run of sample bytes of one X plane (load balancing moves planes between neighbours).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlaneChunk {
    /// The plane.
    pub plane: u32,
    /// Byte offset of this chunk in the plane.
    pub offset: u32,
    /// Bytes used in `bytes`.
    pub len: u16,
    /// Sample bytes.
    pub bytes: [u8; PLANE_CHUNK],
}

impl PlaneChunk {
    pub(super) fn emit(&self, w: &mut Writer<'_>) {
        w.u32(self.plane);
        w.u32(self.offset);
        w.u16(self.len);
        w.bytes(&self.bytes);
    }

    pub(super) fn parse(r: &mut Reader<'_>) -> Result<PlaneChunk, DecodeError> {
        let plane = r.u32()?;
        let offset = r.u32()?;
        let len = r.u16()?;
        if usize::from(len) > PLANE_CHUNK {
            return Err(r.bad("len"));
        }
        Ok(PlaneChunk {
            plane,
            offset,
            len,
            bytes: r.take()?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::*;

    #[test]
    fn a_plane_chunk_round_trips_and_its_length_is_checked() {
        roundtrip(planes());
        // `len`, little-endian at 9..11: its top byte makes it exceed PLANE_CHUNK.
        refuses(planes(), 10, 1, "len");
    }
}
