//! How bit-planes get into [`run_parallel`](super::run_parallel)'s time
//! chunks: the sources' planes ([`SourcePlane`]), the chunks' cells that
//! later chunks' workers read their warm-up planes from, and the pool of
//! chunks filled again in place.

use crate::hot_pixel_mask::HotPixelMask;
use crate::plane::BitPlane;
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};

/// A bit-plane as a source hands it to
/// [`run_parallel`](super::run_parallel), which writes it into a plane of a
/// chunk: a plane of the source's own (just decoded or simulated), which
/// the reader writes at once, so that its memory is freed in the thread
/// that allocated it and used again for the next (freed in bursts by other
/// threads, it faulted in again: a quarter more CPU on a SPAD512S recording);
/// or a plane lent (a reference to one the caller keeps, or one that the
/// writing reads from a file: [`crate::recording::PlaneAt`]), which the
/// reader only passes on and the worker that takes the chunk writes (a
/// 512×512 plane is 32 KB: one thread copying every plane held a 16-core
/// run to ~50,000 planes/s). `E` is the source's error: writing a plane may
/// fail (a file cut short meanwhile).
pub trait SourcePlane<E>: Send {
    /// Whether the reader writes the plane into its chunk (else the worker).
    const WRITTEN_BY_READER: bool;

    /// The plane's width and height.
    fn size(&self) -> (usize, usize);

    /// Writes the plane into `dst`, a plane of its size, hot pixels masked;
    /// `scratch` is the writing thread's buffer, for the source's use.
    fn write_into(
        &self,
        dst: &mut BitPlane,
        mask: Option<&HotPixelMask>,
        scratch: &mut Vec<u8>,
    ) -> Result<(), E>;
}

impl<E> SourcePlane<E> for BitPlane {
    const WRITTEN_BY_READER: bool = true;

    fn size(&self) -> (usize, usize) {
        (self.width(), self.height())
    }

    fn write_into(
        &self,
        dst: &mut BitPlane,
        mask: Option<&HotPixelMask>,
        _: &mut Vec<u8>,
    ) -> Result<(), E> {
        dst.copy_masked(self, mask);
        Ok(())
    }
}

/// The same plane, lent: written by the worker.
impl<E> SourcePlane<E> for &BitPlane {
    const WRITTEN_BY_READER: bool = false;

    fn size(&self) -> (usize, usize) {
        SourcePlane::<E>::size(*self)
    }

    fn write_into(
        &self,
        dst: &mut BitPlane,
        mask: Option<&HotPixelMask>,
        scratch: &mut Vec<u8>,
    ) -> Result<(), E> {
        SourcePlane::<E>::write_into(*self, dst, mask, scratch)
    }
}

/// Writes `plane` into `batch` as its plane `i` (reused if there is one,
/// else a new one pushed: `i ≤ batch.len()`).
pub(super) fn put_plane<E, P: SourcePlane<E>>(
    batch: &mut Vec<BitPlane>,
    i: usize,
    plane: &P,
    mask: Option<&HotPixelMask>,
    scratch: &mut Vec<u8>,
) -> Result<(), E> {
    if i == batch.len() {
        let (w, h) = plane.size();
        batch.push(BitPlane::zeros(w, h));
    }
    plane.write_into(&mut batch[i], mask, scratch)
}

/// Writes `source` into `batch` (whose planes are reused).
pub(super) fn fill_chunk<E, P: SourcePlane<E>>(
    batch: &mut Vec<BitPlane>,
    source: &[P],
    mask: Option<&HotPixelMask>,
    scratch: &mut Vec<u8>,
) -> Result<(), E> {
    for (i, p) in source.iter().enumerate() {
        put_plane(batch, i, p, mask, scratch)?;
    }
    batch.truncate(source.len());
    Ok(())
}

/// A chunk's planes (hot pixels masked) once the reader or the worker that
/// took it has written them: the workers of the chunks after it read their
/// warm-up planes from here, and wait for it if they get there first.
#[derive(Default)]
pub(super) struct ChunkCell {
    state: Mutex<CellState>,
    filled: Condvar,
}

#[derive(Default)]
pub(super) enum CellState {
    #[default]
    Filling,
    Filled(Arc<Vec<BitPlane>>),
    /// Its worker stopped before filling it (a source error, or a panic):
    /// whoever waits stops too.
    Abandoned,
}

impl ChunkCell {
    fn lock(&self) -> MutexGuard<'_, CellState> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    pub(super) fn set(&self, state: CellState) {
        *self.lock() = state;
        self.filled.notify_all();
    }

    /// The chunk's planes once filled; `None` if its worker gave up.
    pub(super) fn wait(&self) -> Option<Arc<Vec<BitPlane>>> {
        let mut state = self.lock();
        loop {
            match &*state {
                CellState::Filling => {
                    state = self
                        .filled
                        .wait(state)
                        .unwrap_or_else(PoisonError::into_inner)
                }
                CellState::Filled(planes) => return Some(planes.clone()),
                CellState::Abandoned => return None,
            }
        }
    }
}

/// Marks its cell abandoned unless the chunk was filled: a worker that
/// fails or panics while writing must not leave the next chunks' workers
/// waiting.
pub(super) struct Filling<'a>(pub(super) &'a ChunkCell);

impl Filling<'_> {
    pub(super) fn fill(self, planes: Arc<Vec<BitPlane>>) {
        self.0.set(CellState::Filled(planes));
        // Filled: not abandoned.
        std::mem::forget(self);
    }
}

impl Drop for Filling<'_> {
    fn drop(&mut self) {
        self.0.set(CellState::Abandoned);
    }
}

/// Every chunk's planes while anyone holds them: a chunk only the pool holds
/// is filled again in place, so that planes are not allocated by the
/// reader or the workers and freed in bursts by the back end (on some
/// machines the heap then returns its pages and every chunk faults them in
/// again).
#[derive(Default)]
pub(super) struct ChunkPool(Mutex<Vec<Arc<Vec<BitPlane>>>>);

impl ChunkPool {
    /// A chunk's planes to fill again, or an empty one.
    pub(super) fn take(&self) -> Vec<BitPlane> {
        let mut pool = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        // A count of one: nobody else holds the chunk, nor can get it again.
        pool.iter()
            .position(|c| Arc::strong_count(c) == 1)
            .and_then(|i| Arc::try_unwrap(pool.swap_remove(i)).ok())
            .unwrap_or_default()
    }

    pub(super) fn keep(&self, chunk: &Arc<Vec<BitPlane>>) {
        self.0
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(chunk.clone());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chunk_cell_wakes_its_waiters_filled_or_abandoned() {
        let cell = ChunkCell::default();
        let planes = Arc::new(vec![BitPlane::zeros(3, 2)]);
        std::thread::scope(|s| {
            let waiter = s.spawn(|| cell.wait());
            std::thread::sleep(std::time::Duration::from_millis(20));
            Filling(&cell).fill(planes.clone());
            let got = waiter.join().unwrap().expect("filled");
            assert!(Arc::ptr_eq(&got, &planes));
        });
        // A second wait returns at once.
        assert!(cell.wait().is_some());

        let cell = ChunkCell::default();
        std::thread::scope(|s| {
            let waiter = s.spawn(|| cell.wait());
            std::thread::sleep(std::time::Duration::from_millis(20));
            // The worker stopped without filling it.
            drop(Filling(&cell));
            assert!(waiter.join().unwrap().is_none());
        });
    }

    #[test]
    fn the_pool_reuses_only_a_chunk_nobody_else_holds() {
        let pool = ChunkPool::default();
        assert!(pool.take().is_empty());
        let chunk = Arc::new(vec![BitPlane::zeros(4, 4); 3]);
        pool.keep(&chunk);
        // Held by the back end: a new one.
        assert!(pool.take().is_empty());
        drop(chunk);
        assert_eq!(pool.take().len(), 3);
        // Taken: the pool no longer has it.
        assert!(pool.take().is_empty());
    }

    #[test]
    fn fill_chunk_reuses_and_grows_and_masks() {
        let (w, h) = (10, 3);
        let mut ones = BitPlane::zeros(w, h);
        for i in 0..w * h {
            ones.set(i % w, i / w, true);
        }
        let (mask, _) = crate::hot_pixel_mask::HotPixelMask::from_pixels(w, h, &[(2, 1)]);
        let mut batch = vec![BitPlane::zeros(w, h); 2];
        let mut scratch = Vec::new();
        fill_chunk::<(), _>(
            &mut batch,
            &[&ones, &ones, &ones],
            Some(&mask),
            &mut scratch,
        )
        .unwrap();
        assert_eq!(batch.len(), 3);
        for p in &batch {
            assert_eq!(p.count_ones(), w * h - 1);
            assert!(!p.get(2, 1));
        }
        fill_chunk::<(), _>(&mut batch, &[BitPlane::zeros(w, h)], None, &mut scratch).unwrap();
        assert_eq!(batch.len(), 1);
        assert_eq!(batch[0].count_ones(), 0);
    }
}
