//! Member names inside a shard: `KEY.FIELD` plus the compression suffix of arrays.
//!
//! Fields are `cls`, `json`, `npy` (the image) and `rSIDE.npy` (a downscaled copy); arrays
//! may carry the suffix of [`Compression`] (`.gz`, `.zst`). Writers build names with
//! [`member_name`], readers take them apart with [`MemberName::parse`]; the suffixes
//! themselves are [`Compression::suffix`] and [`Compression::split_suffix`].

use bettimill_shard::{split_key, Compression};

/// The field of a sample's class index.
pub const CLASS_FIELD: &str = "cls";
/// The field of a sample's label.
pub const LABEL_FIELD: &str = "json";
/// The field of a sample's image.
pub const IMAGE_FIELD: &str = "npy";

/// The name of a member: `KEY.FIELD`, with `compression`'s suffix for arrays (fields
/// ending in `npy`) and none for any other field.
pub fn member_name(key: &str, field: &str, compression: Compression) -> String {
    if is_array_field(field) {
        format!("{key}.{field}{}", compression.suffix())
    } else {
        format!("{key}.{field}")
    }
}

/// Whether `field` (without compression suffix) holds an `.npy` array.
pub fn is_array_field(field: &str) -> bool {
    field.ends_with(IMAGE_FIELD)
}

/// A member name taken apart.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemberName<'a> {
    /// The WebDataset key (everything before the first dot of the last path component).
    pub key: &'a str,
    /// The field without compression suffix (`cls`, `json`, `npy`, `r16.npy`, ...).
    pub field: &'a str,
    /// The compression the suffix names ([`Compression::None`] without one).
    pub compression: Compression,
}

impl<'a> MemberName<'a> {
    /// Splits `name` into key, field and compression; `None` when it has no field.
    pub fn parse(name: &'a str) -> Option<MemberName<'a>> {
        let (key, field) = split_key(name)?;
        let (field, compression) = Compression::split_suffix(field);
        Some(MemberName {
            key,
            field,
            compression,
        })
    }

    /// Whether the member is the label (`KEY.json`).
    pub fn is_label(&self) -> bool {
        self.field == LABEL_FIELD
    }

    /// Whether the member is an array (the image or a downscaled copy).
    pub fn is_array(&self) -> bool {
        is_array_field(self.field)
    }

    /// Whether the member is the full-resolution image (`KEY.npy`, compressed or not).
    pub fn is_image(&self) -> bool {
        self.field == IMAGE_FIELD
    }

    /// The side of a downscaled copy (`KEY.rSIDE.npy`), `None` for anything else.
    pub fn resolution(&self) -> Option<u32> {
        self.field
            .strip_suffix(".npy")?
            .strip_prefix('r')?
            .parse()
            .ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for compression in [Compression::None, Compression::Gzip, Compression::Zstd] {
            for field in ["cls", "json", "npy", "r16.npy"] {
                let name = member_name("train/s000001", field, compression);
                let parsed = MemberName::parse(&name).unwrap();
                assert_eq!(parsed.key, "train/s000001");
                assert_eq!(parsed.field, field);
                let expected = if is_array_field(field) {
                    compression
                } else {
                    Compression::None
                };
                assert_eq!(parsed.compression, expected, "{name}");
            }
        }
        assert_eq!(member_name("s1", "json", Compression::Gzip), "s1.json");
        assert_eq!(member_name("s1", "npy", Compression::Zstd), "s1.npy.zst");
        let copy = MemberName::parse("s1.r8.npy.gz").unwrap();
        assert_eq!(copy.resolution(), Some(8));
        assert!(copy.is_array() && !copy.is_image());
        assert!(MemberName::parse("s1.npy").unwrap().is_image());
        assert_eq!(MemberName::parse("s1.npy").unwrap().resolution(), None);
        assert!(MemberName::parse("nodot").is_none());
    }
}
