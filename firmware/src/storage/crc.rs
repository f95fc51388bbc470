//! CRC-32 (IEEE 802.3, reflected, as zlib and crc32fast), table-less: the records (settings,
//! paused job) carry it, the store's headers and frames too. The inputs are small, and a
//! table costs flash (see `Cargo.toml`).

const CRC32: crc::Crc<u32, crc::NoTable> =
    crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);

/// CRC-32 of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    CRC32.checksum(bytes)
}

/// CRC-32 of `parts` one after the other (as of their concatenation).
pub fn crc32_parts(parts: &[&[u8]]) -> u32 {
    let mut d = CRC32.digest();
    for p in parts {
        d.update(p);
    }
    d.finalize()
}
