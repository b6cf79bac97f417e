//! The 64-bit CRC of a message body.
//!
//! OpenIGTLink uses the CRC of ECMA-182: polynomial 0x42F0E1EBA9EA3693, initial value 0,
//! bits not reflected, no final XOR (`crc64()` of the reference library's `igtl_util.c`,
//! called as `crc64(body, size, crc64(0, 0, 0))`, and pyigtl's `crcmod` parameters). This is
//! the catalogue's CRC-64/ECMA-182, check value `0x6C40DF5F0B497347` for `"123456789"`.
//! The CRC covers the whole body: for version-3 messages that is the extended header, the
//! content and the metadata.

use crc::{Crc, CRC_64_ECMA_182};

const ECMA_182: Crc<u64> = Crc::<u64>::new(&CRC_64_ECMA_182);

/// CRC-64 of `body` as OpenIGTLink computes it (the header's CRC field).
pub fn body_crc(body: &[u8]) -> u64 {
    ECMA_182.checksum(body)
}
