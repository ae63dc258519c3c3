//! The fixed-width little-endian fields every message is made of, written and read in order,
//! so that each message's own codec says only which fields, in which order, and their range.
//!
//! Invariant: the writer never writes past the buffer and the reader never reads past the
//! message, whatever a codec asks (a wrong length is an error, never a panic); every error
//! says why bytes are not a message ([`DecodeError`]).

use super::reply::Reply;
use crate::node::kind::{MsgKind, MAX_MSG_LEN};
use core::fmt;
use glam::Vec3;

/// Why bytes are not a message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DecodeError {
    /// No bytes.
    Empty,
    /// The tag names no kind.
    UnknownKind(u8),
    /// The length is not the kind's.
    Length {
        /// The kind.
        kind: MsgKind,
        /// Its length.
        expected: usize,
        /// Bytes given.
        actual: usize,
    },
    /// A field holds a value outside its range.
    Field {
        /// The kind.
        kind: MsgKind,
        /// The field.
        field: &'static str,
    },
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            DecodeError::Empty => write!(f, "empty message"),
            DecodeError::UnknownKind(t) => write!(f, "unknown message kind {t}"),
            DecodeError::Length {
                kind,
                expected,
                actual,
            } => {
                write!(f, "{kind:?} message of {actual} bytes; it has {expected}")
            }
            DecodeError::Field { kind, field } => {
                write!(f, "{kind:?} message: field {field} out of range")
            }
        }
    }
}

impl core::error::Error for DecodeError {}

/// Writes a message's fields in order, little-endian, into its buffer.
pub(super) struct Writer<'a> {
    buf: &'a mut [u8; MAX_MSG_LEN],
    at: usize,
}

impl<'a> Writer<'a> {
    /// A writer at the start of `buf`.
    pub(super) fn new(buf: &'a mut [u8; MAX_MSG_LEN]) -> Self {
        Writer { buf, at: 0 }
    }
    /// Bytes written.
    pub(super) fn len(&self) -> usize {
        self.at
    }
    pub(super) fn bytes(&mut self, b: &[u8]) {
        // Lengths are constants within MAX_MSG_LEN; `get_mut` keeps even a mistake panic-free.
        if let Some(dst) = self.buf.get_mut(self.at..self.at + b.len()) {
            dst.copy_from_slice(b);
        }
        self.at += b.len();
    }
    pub(super) fn u8(&mut self, v: u8) {
        self.bytes(&[v]);
    }
    pub(super) fn u16(&mut self, v: u16) {
        self.bytes(&v.to_le_bytes());
    }
    pub(super) fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }
    pub(super) fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
    pub(super) fn f32(&mut self, v: f32) {
        self.bytes(&v.to_le_bytes());
    }
    pub(super) fn vec3(&mut self, v: Vec3) {
        self.f32(v.x);
        self.f32(v.y);
        self.f32(v.z);
    }
    pub(super) fn reply(&mut self, r: &Reply) {
        self.u16(r.home);
        self.u16(r.slot);
        self.u8(r.hit);
        self.u8(r.light);
    }
}

/// Reads a message's fields in order, past its tag; every error names the message's kind.
pub(super) struct Reader<'a> {
    buf: &'a [u8],
    at: usize,
    kind: MsgKind,
}

impl<'a> Reader<'a> {
    /// A reader of message `kind`'s bytes `buf`, past the tag.
    pub(super) fn new(buf: &'a [u8], kind: MsgKind) -> Self {
        Reader { buf, at: 1, kind }
    }
    pub(super) fn take<const N: usize>(&mut self) -> Result<[u8; N], DecodeError> {
        let slice = self
            .buf
            .get(self.at..self.at + N)
            .ok_or(DecodeError::Field {
                kind: self.kind,
                field: "length",
            })?;
        self.at += N;
        let mut out = [0u8; N];
        out.copy_from_slice(slice);
        Ok(out)
    }
    pub(super) fn u8(&mut self) -> Result<u8, DecodeError> {
        Ok(self.take::<1>()?[0])
    }
    pub(super) fn u16(&mut self) -> Result<u16, DecodeError> {
        Ok(u16::from_le_bytes(self.take()?))
    }
    pub(super) fn u32(&mut self) -> Result<u32, DecodeError> {
        Ok(u32::from_le_bytes(self.take()?))
    }
    pub(super) fn u64(&mut self) -> Result<u64, DecodeError> {
        Ok(u64::from_le_bytes(self.take()?))
    }
    pub(super) fn f32(&mut self) -> Result<f32, DecodeError> {
        Ok(f32::from_le_bytes(self.take()?))
    }
    pub(super) fn vec3(&mut self) -> Result<Vec3, DecodeError> {
        Ok(Vec3::new(self.f32()?, self.f32()?, self.f32()?))
    }
    pub(super) fn bool(&mut self, field: &'static str) -> Result<bool, DecodeError> {
        match self.u8()? {
            0 => Ok(false),
            1 => Ok(true),
            _ => Err(self.bad(field)),
        }
    }
    pub(super) fn reply(&mut self) -> Result<Reply, DecodeError> {
        Ok(Reply {
            home: self.u16()?,
            slot: self.u16()?,
            hit: self.u8()?,
            light: self.u8()?,
        })
    }
    pub(super) fn bad(&self, field: &'static str) -> DecodeError {
        DecodeError::Field {
            kind: self.kind,
            field,
        }
    }
}
