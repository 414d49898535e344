//! Per-attribute columns that grow by one entry per frame (a streamed bake's
//! value handles or text offsets), kept in memory one block of frames at a
//! time and spilled to a scratch file beside the output, so a writer's
//! memory does not grow with the length of the shot (issue 10).
//!
//! The scratch file holds full blocks one after another; within a block,
//! each column's entries are contiguous, so reading a column back is one
//! read per block.

use std::fs::File;
use std::io::Write;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

use bytemuck::Pod;

use super::atomic::TempFile;
use crate::error::{Error, Result};

/// Frames per block: at most `columns × BLOCK` entries stay in memory
/// (126 attributes × 1,024 frames × 8 bytes ≈ 1 MB for the Dog bake).
pub const BLOCK: usize = 1024;

/// Columns of `T`, filled a row (a frame) at a time.
pub struct ColumnSpill<T: Pod> {
    target: PathBuf,
    columns: usize,
    block: usize,
    /// The current block: per column, fewer than `block` entries.
    current: Vec<Vec<T>>,
    /// Created when the first block is full.
    file: Option<(TempFile, File)>,
    /// Full blocks written to `file`.
    spilled: usize,
}

impl<T: Pod> ColumnSpill<T> {
    /// Columns for the output `target` (the scratch file goes beside it).
    pub fn new(target: &Path, columns: usize) -> Self {
        Self::with_block(target, columns, BLOCK)
    }

    /// With `block` rows per block (tests use small ones).
    pub fn with_block(target: &Path, columns: usize, block: usize) -> Self {
        ColumnSpill {
            target: target.to_path_buf(),
            columns,
            block: block.max(1),
            current: (0..columns).map(|_| Vec::new()).collect(),
            file: None,
            spilled: 0,
        }
    }

    /// Appends one entry to every column (`row[c]` to column `c`).
    pub fn push_row(&mut self, row: &[T]) -> Result<()> {
        if row.len() != self.columns {
            return Err(Error::msg(format!(
                "internal: a row of {} entries for {} columns",
                row.len(),
                self.columns
            )));
        }
        for (col, &v) in self.current.iter_mut().zip(row) {
            if col.capacity() == 0 {
                col.reserve_exact(self.block);
            }
            col.push(v);
        }
        if self.rows_in_block() == self.block {
            self.spill()?;
        }
        Ok(())
    }

    /// Rows pushed so far.
    pub fn rows(&self) -> usize {
        self.spilled * self.block + self.rows_in_block()
    }

    fn rows_in_block(&self) -> usize {
        self.current.first().map_or(0, Vec::len)
    }

    fn spill(&mut self) -> Result<()> {
        if self.file.is_none() {
            self.file = Some(TempFile::create(&self.target, ".frames")?);
        }
        let Some((_, file)) = self.file.as_mut() else {
            return Ok(());
        };
        for col in &mut self.current {
            file.write_all(bytemuck::cast_slice(col))
                .map_err(|e| Error::msg(format!("cannot write a scratch file: {e}")).in_file(&self.target))?;
            col.clear();
        }
        self.spilled += 1;
        Ok(())
    }

    /// Every entry of column `c`, in row order.
    pub fn column(&self, c: usize) -> Result<Vec<T>> {
        let Some(current) = self.current.get(c) else {
            return Err(Error::msg(format!("internal: no column {c} of {}", self.columns)));
        };
        let mut out = Vec::with_capacity(self.rows());
        if let Some((_, file)) = &self.file {
            let size = std::mem::size_of::<T>();
            let mut block = vec![T::zeroed(); self.block];
            for b in 0..self.spilled {
                let offset = ((b * self.columns + c) * self.block * size) as u64;
                file.read_exact_at(bytemuck::cast_slice_mut(&mut block), offset)
                    .map_err(|e| Error::msg(format!("cannot read a scratch file: {e}")).in_file(&self.target))?;
                out.extend_from_slice(&block);
            }
        }
        out.extend_from_slice(current);
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder() -> crate::usd_io::atomic::TempDir {
        crate::usd_io::atomic::TempDir::new().unwrap()
    }

    #[test]
    fn columns_read_back_in_order_across_blocks() {
        let dir = folder();
        let target = dir.path().join("out.usdc");
        for rows in [0usize, 1, 3, 4, 5, 11, 12] {
            let mut s = ColumnSpill::<u64>::with_block(&target, 3, 4);
            for r in 0..rows {
                let row: Vec<u64> = (0..3).map(|c| (r * 10 + c) as u64).collect();
                s.push_row(&row).unwrap();
            }
            assert_eq!(s.rows(), rows);
            for c in 0..3 {
                let want: Vec<u64> = (0..rows).map(|r| (r * 10 + c) as u64).collect();
                assert_eq!(s.column(c).unwrap(), want, "rows {rows} column {c}");
            }
            // A scratch file exists only once a block is full, and goes with the spill.
            let scratch = |d: &Path| std::fs::read_dir(d).unwrap().count();
            assert_eq!(scratch(dir.path()), usize::from(rows >= 4));
            drop(s);
            assert_eq!(scratch(dir.path()), 0);
        }
    }

    #[test]
    fn pairs_and_wrong_rows() {
        let dir = folder();
        let mut s = ColumnSpill::<[u64; 2]>::with_block(&dir.path().join("a.usda"), 2, 2);
        for r in 0..5u64 {
            s.push_row(&[[r, 1], [r, 2]]).unwrap();
        }
        assert_eq!(s.column(1).unwrap(), (0..5u64).map(|r| [r, 2]).collect::<Vec<_>>());
        assert!(s.push_row(&[[0, 0]]).is_err());
        assert!(s.column(2).is_err());
    }

    #[test]
    fn a_block_is_reserved_once_and_never_outgrown() {
        // The module's memory bound: at most `block` entries per column in
        // memory, reserved when the block starts rather than grown by doubling.
        let dir = folder();
        let mut s = ColumnSpill::<u64>::with_block(&dir.path().join("out.usdc"), 2, 100);
        for r in 0..250u64 {
            s.push_row(&[r, r + 1]).unwrap();
            for col in &s.current {
                assert!(col.capacity() <= 100, "after row {r}: capacity {}", col.capacity());
            }
        }
        assert_eq!(s.column(1).unwrap(), (1..251u64).collect::<Vec<_>>());
    }
}
