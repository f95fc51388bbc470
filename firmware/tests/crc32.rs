//! The stored records' CRC (`firmware::storage::crc32`, table-less from the `crc` crate) is the
//! CRC-32 that crc32fast (used before, and by zlib) computes: records saved by an earlier image
//! still read back.
use firmware::storage::crc32;

#[test]
fn same_as_crc32fast() {
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926, "the CRC-32 check value");
    assert_eq!(crc32(b""), crc32fast::hash(b""));
    let mut data = [0u8; 1031];
    for (i, b) in data.iter_mut().enumerate() {
        *b = (i * 7 + i / 13) as u8;
    }
    for n in [1, 4, 63, 64, 65, 512, 1031] {
        assert_eq!(crc32(&data[..n]), crc32fast::hash(&data[..n]), "{n} bytes");
    }
}
