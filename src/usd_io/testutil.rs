//! Test helpers for the readers: a stage from usda text in memory.

use super::memory::open_bytes;
use super::stage::StageReader;

/// A stage whose root layer is `usda`, opened in memory (nothing is read
/// from or written to the file name it is given).
pub(crate) fn stage_from_usda(usda: &str) -> StageReader {
    let path = std::env::temp_dir().join("painterly_test_stage.usda");
    open_bytes(usda.as_bytes().to_vec(), &path).unwrap()
}
