//! Decoded pixel values of one page, in the file's own sample type.

use tiff::decoder::DecodingResult;

/// The samples of one decoded page, row-major, in the file's sample type.
#[derive(Clone, Debug, PartialEq)]
pub enum Samples {
    /// 8-bit unsigned.
    U8(Vec<u8>),
    /// 16-bit unsigned (camera ADU).
    U16(Vec<u16>),
    /// 32-bit unsigned.
    U32(Vec<u32>),
    /// 64-bit unsigned.
    U64(Vec<u64>),
    /// 8-bit signed.
    I8(Vec<i8>),
    /// 16-bit signed.
    I16(Vec<i16>),
    /// 32-bit signed.
    I32(Vec<i32>),
    /// 64-bit signed.
    I64(Vec<i64>),
    /// 32-bit float.
    F32(Vec<f32>),
    /// 64-bit float.
    F64(Vec<f64>),
}

impl Samples {
    /// Number of samples.
    pub fn len(&self) -> usize {
        match self {
            Samples::U8(v) => v.len(),
            Samples::U16(v) => v.len(),
            Samples::U32(v) => v.len(),
            Samples::U64(v) => v.len(),
            Samples::I8(v) => v.len(),
            Samples::I16(v) => v.len(),
            Samples::I32(v) => v.len(),
            Samples::I64(v) => v.len(),
            Samples::F32(v) => v.len(),
            Samples::F64(v) => v.len(),
        }
    }

    /// True if there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The sample type's name: `u8`, `u16`, ... `f64`.
    pub fn type_name(&self) -> &'static str {
        match self {
            Samples::U8(_) => "u8",
            Samples::U16(_) => "u16",
            Samples::U32(_) => "u32",
            Samples::U64(_) => "u64",
            Samples::I8(_) => "i8",
            Samples::I16(_) => "i16",
            Samples::I32(_) => "i32",
            Samples::I64(_) => "i64",
            Samples::F32(_) => "f32",
            Samples::F64(_) => "f64",
        }
    }

    /// The values as f64 (exact except for 64-bit integers above 2⁵³).
    pub fn into_f64(self) -> Vec<f64> {
        match self {
            Samples::U8(v) => v.into_iter().map(f64::from).collect(),
            Samples::U16(v) => v.into_iter().map(f64::from).collect(),
            Samples::U32(v) => v.into_iter().map(f64::from).collect(),
            Samples::U64(v) => v.into_iter().map(|x| x as f64).collect(),
            Samples::I8(v) => v.into_iter().map(f64::from).collect(),
            Samples::I16(v) => v.into_iter().map(f64::from).collect(),
            Samples::I32(v) => v.into_iter().map(f64::from).collect(),
            Samples::I64(v) => v.into_iter().map(|x| x as f64).collect(),
            Samples::F32(v) => v.into_iter().map(f64::from).collect(),
            Samples::F64(v) => v,
        }
    }
}

impl Samples {
    /// The decoder's result in this crate's type.
    pub(crate) fn from_decoded(d: DecodingResult) -> Self {
        match d {
            DecodingResult::U8(v) => Samples::U8(v),
            DecodingResult::U16(v) => Samples::U16(v),
            DecodingResult::U32(v) => Samples::U32(v),
            DecodingResult::U64(v) => Samples::U64(v),
            DecodingResult::I8(v) => Samples::I8(v),
            DecodingResult::I16(v) => Samples::I16(v),
            DecodingResult::I32(v) => Samples::I32(v),
            DecodingResult::I64(v) => Samples::I64(v),
            DecodingResult::F32(v) => Samples::F32(v),
            DecodingResult::F64(v) => Samples::F64(v),
        }
    }
}
