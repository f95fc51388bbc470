//! Boot Parameter Block

use crate::{
    blockdevice::BlockCount,
    fat::{FatType, OnDiskDirEntry},
};
use byteorder::{ByteOrder, LittleEndian};

/// A Boot Parameter Block.
///
/// This is the first sector of a FAT formatted partition, and it describes
/// various properties of the FAT filesystem.
pub struct Bpb<'a> {
    data: &'a [u8; 512],
    pub(crate) fat_type: FatType,
    cluster_count: u32,
}

impl<'a> Bpb<'a> {
    pub(crate) const FOOTER_VALUE: u16 = 0xAA55;

    /// Attempt to parse a Boot Parameter Block from a 512 byte sector.
    pub fn create_from_bytes(data: &[u8; 512]) -> Result<Bpb, &'static str> {
        let mut bpb = Bpb {
            data,
            fat_type: FatType::Fat16,
            cluster_count: 0,
        };
        if bpb.footer() != Self::FOOTER_VALUE {
            return Err("Bad BPB footer");
        }

        // Every field the arithmetic below and the rest of the crate rely on is checked
        // first: a damaged or foreign boot sector is a format error, never a division by
        // zero, an overflow or a cluster outside the volume.
        let blocks_per_cluster = u32::from(bpb.blocks_per_cluster());
        if !blocks_per_cluster.is_power_of_two() {
            // Also rejects 0 (a division by zero below).
            return Err("Invalid number of blocks per cluster");
        }
        if bpb.reserved_block_count() == 0 {
            return Err("Invalid reserved block count");
        }
        if bpb.num_fats() == 0 {
            return Err("Invalid number of FATs");
        }
        if bpb.fat_size() == 0 {
            return Err("Invalid FAT size");
        }
        // The root directory area is whole blocks of entries (Linux refuses a volume whose
        // count is not, as "bogus number of directory entries").
        let root_bytes = u32::from(bpb.root_entries_count()) * OnDiskDirEntry::LEN_U32;
        if root_bytes.checked_rem(u32::from(bpb.bytes_per_block())) != Some(0) {
            return Err("Invalid root entry count");
        }
        let root_dir_blocks =
            BlockCount::from_bytes(u32::from(bpb.root_entries_count()) * OnDiskDirEntry::LEN_U32).0;
        let non_data_blocks = u32::from(bpb.num_fats())
            .checked_mul(bpb.fat_size())
            .and_then(|fats| fats.checked_add(u32::from(bpb.reserved_block_count())))
            .and_then(|n| n.checked_add(root_dir_blocks))
            .ok_or("Invalid FAT size")?;
        let data_blocks = bpb
            .total_blocks()
            .checked_sub(non_data_blocks)
            .ok_or("Volume smaller than its FATs")?;
        bpb.cluster_count = data_blocks / blocks_per_cluster;
        if bpb.cluster_count < 4085 {
            return Err("FAT12 is unsupported");
        } else if bpb.cluster_count < 65525 {
            bpb.fat_type = FatType::Fat16;
        } else if bpb.cluster_count <= 0x0FFF_FFF5 {
            bpb.fat_type = FatType::Fat32;
        } else {
            // FAT32 cluster numbers have 28 bits.
            return Err("Too many clusters");
        }
        // The FAT must have an entry for every cluster (and the two reserved ones), or a
        // cluster number read from it could point past its end.
        let entry_bytes = match bpb.fat_type {
            FatType::Fat16 => 2,
            FatType::Fat32 => 4,
        };
        let fat_entries =
            u64::from(bpb.fat_size()) * u64::from(bpb.bytes_per_block()) / entry_bytes;
        if fat_entries < u64::from(bpb.cluster_count) + 2 {
            return Err("FAT too small for the volume");
        }
        match bpb.fat_type {
            // FAT16 keeps its root directory in a fixed area (FAT32 in a cluster chain).
            FatType::Fat16 if bpb.root_entries_count() == 0 => Err("Invalid root entry count"),
            // The 16-bit FAT size is FAT16's, and 0 on FAT32.
            FatType::Fat16 if bpb.fat_size16() == 0 => Err("Invalid FAT size"),
            FatType::Fat16 => Ok(bpb),
            FatType::Fat32 if bpb.root_entries_count() != 0 => Err("Invalid root entry count"),
            FatType::Fat32 if bpb.fat_size16() != 0 => Err("Invalid FAT size"),
            FatType::Fat32
                if !(2..=bpb.cluster_count + 1).contains(&bpb.first_root_dir_cluster()) =>
            {
                Err("Invalid root directory cluster")
            }
            FatType::Fat32 if bpb.fs_ver() == 0 => {
                // Only support FAT32 version 0.0
                Ok(bpb)
            }
            _ => Err("Invalid FAT format"),
        }
    }

    // FAT16/FAT32
    define_field!(bytes_per_block, u16, 11);
    define_field!(blocks_per_cluster, u8, 13);
    define_field!(reserved_block_count, u16, 14);
    define_field!(num_fats, u8, 16);
    define_field!(root_entries_count, u16, 17);
    define_field!(total_blocks16, u16, 19);
    define_field!(media, u8, 21);
    define_field!(fat_size16, u16, 22);
    define_field!(blocks_per_track, u16, 24);
    define_field!(num_heads, u16, 26);
    define_field!(hidden_blocks, u32, 28);
    define_field!(total_blocks32, u32, 32);
    define_field!(footer, u16, 510);

    // FAT32 only
    define_field!(fat_size32, u32, 36);
    define_field!(fs_ver, u16, 42);
    define_field!(first_root_dir_cluster, u32, 44);
    define_field!(fs_info, u16, 48);
    define_field!(backup_boot_block, u16, 50);

    /// Get the OEM name string for this volume
    pub fn oem_name(&self) -> &[u8] {
        &self.data[3..11]
    }

    // FAT16/FAT32 functions

    /// Get the Volume Label string for this volume
    pub fn volume_label(&self) -> [u8; 11] {
        let mut result = [0u8; 11];
        match self.fat_type {
            FatType::Fat16 => result.copy_from_slice(&self.data[43..=53]),
            FatType::Fat32 => result.copy_from_slice(&self.data[71..=81]),
        }
        result
    }

    // FAT32 only functions

    /// On a FAT32 volume, return the free block count from the Info Block. On
    /// a FAT16 volume, returns None.
    pub fn fs_info_block(&self) -> Option<BlockCount> {
        match self.fat_type {
            FatType::Fat16 => None,
            FatType::Fat32 => Some(BlockCount(u32::from(self.fs_info()))),
        }
    }

    // Magic functions that get the right FAT16/FAT32 result

    /// Get the size of the File Allocation Table in blocks.
    pub fn fat_size(&self) -> u32 {
        let result = u32::from(self.fat_size16());
        if result != 0 {
            result
        } else {
            self.fat_size32()
        }
    }

    /// Get the total number of blocks in this filesystem.
    pub fn total_blocks(&self) -> u32 {
        let result = u32::from(self.total_blocks16());
        if result != 0 {
            result
        } else {
            self.total_blocks32()
        }
    }

    /// Get the total number of clusters in this filesystem.
    pub fn total_clusters(&self) -> u32 {
        self.cluster_count
    }
}

// ****************************************************************************
//
// End Of File
//
// ****************************************************************************
