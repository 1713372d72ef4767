//! Undo/redo per stroke: each edit stores the pixels it changed, before and
//! after, in 64x64 tiles copied on first touch.

use ifd_image::Image;
use ifd_planar::PixelRect;

/// Side of the tiles in which edits save pixels.
pub const TILE: usize = 64;

/// The pixels of `rect` (interleaved, row-major).
#[must_use]
pub fn extract(image: &Image, rect: PixelRect) -> Vec<f32> {
    let (w, c) = (image.width(), image.channels());
    let mut out = Vec::with_capacity(rect.area() * c);
    for y in rect.y0..rect.y0 + rect.height {
        let i = (y * w + rect.x0) * c;
        out.extend_from_slice(&image.data()[i..i + rect.width * c]);
    }
    out
}

/// Writes `pixels` (as [`extract`] returns them) into `rect` of `image`.
pub fn paste(image: &mut Image, rect: PixelRect, pixels: &[f32]) {
    let (w, c) = (image.width(), image.channels());
    let row = rect.width * c;
    for (j, src) in pixels.chunks_exact(row).enumerate() {
        let i = ((rect.y0 + j) * w + rect.x0) * c;
        image.data_mut()[i..i + row].copy_from_slice(src);
    }
}

/// One tile of an edit.
#[derive(Clone, Debug)]
struct TileEdit {
    rect: PixelRect,
    before: Vec<f32>,
    after: Vec<f32>,
}

/// The pixels one stroke changed.
#[derive(Clone, Debug, Default)]
pub struct Edit {
    id: u64,
    tiles: Vec<TileEdit>,
    /// Bounding rectangle of the changed tiles.
    rect: Option<PixelRect>,
}

impl Edit {
    /// Bounding rectangle of the pixels the edit may have changed.
    #[must_use]
    pub fn rect(&self) -> Option<PixelRect> {
        self.rect
    }

    fn bytes(&self) -> usize {
        self.tiles
            .iter()
            .map(|t| (t.before.len() + t.after.len()) * 4)
            .sum()
    }
}

/// Collects the "before" pixels of a stroke as it touches new tiles.
#[derive(Clone, Debug)]
pub struct EditRecorder {
    tiles_x: usize,
    touched: Vec<bool>,
    edit: Edit,
}

impl EditRecorder {
    /// For an image of this size.
    #[must_use]
    pub fn new(image: &Image) -> Self {
        let tiles_x = image.width().div_ceil(TILE);
        let tiles_y = image.height().div_ceil(TILE);
        Self {
            tiles_x,
            touched: vec![false; tiles_x * tiles_y],
            edit: Edit::default(),
        }
    }

    /// Call before changing the pixels of `rect`: saves the tiles it touches
    /// for the first time.
    pub fn before_change(&mut self, image: &Image, rect: PixelRect) {
        if rect.width == 0 || rect.height == 0 {
            return;
        }
        let (w, h) = (image.width(), image.height());
        for ty in rect.y0 / TILE..=(rect.y0 + rect.height - 1) / TILE {
            for tx in rect.x0 / TILE..=(rect.x0 + rect.width - 1) / TILE {
                let k = ty * self.tiles_x + tx;
                if self.touched[k] {
                    continue;
                }
                self.touched[k] = true;
                let t = PixelRect {
                    x0: tx * TILE,
                    y0: ty * TILE,
                    width: TILE.min(w - tx * TILE),
                    height: TILE.min(h - ty * TILE),
                };
                self.edit.rect = Some(self.edit.rect.map_or(t, |r| r.union(t)));
                self.edit.tiles.push(TileEdit {
                    rect: t,
                    before: extract(image, t),
                    after: Vec::new(),
                });
            }
        }
    }

    /// Ends the stroke: records the "after" pixels. `None` if nothing was touched.
    #[must_use]
    pub fn finish(mut self, image: &Image) -> Option<Edit> {
        if self.edit.tiles.is_empty() {
            return None;
        }
        for t in &mut self.edit.tiles {
            t.after = extract(image, t.rect);
        }
        Some(self.edit)
    }
}

/// Undo and redo stacks of edits, bounded in memory (oldest edits dropped).
#[derive(Clone, Debug)]
pub struct History {
    undo: Vec<Edit>,
    redo: Vec<Edit>,
    limit_bytes: usize,
    next_id: u64,
}

impl Default for History {
    fn default() -> Self {
        Self::new(1 << 30)
    }
}

impl History {
    /// Keeps at most `limit_bytes` of undo data (at least the latest edit).
    #[must_use]
    pub fn new(limit_bytes: usize) -> Self {
        Self {
            undo: Vec::new(),
            redo: Vec::new(),
            limit_bytes,
            next_id: 1,
        }
    }

    /// Records a new edit (already applied); clears the redo stack.
    pub fn push(&mut self, mut edit: Edit) {
        edit.id = self.next_id;
        self.next_id += 1;
        self.redo.clear();
        self.undo.push(edit);
        let mut total: usize = self.undo.iter().map(Edit::bytes).sum();
        while total > self.limit_bytes && self.undo.len() > 1 {
            total -= self.undo.remove(0).bytes();
        }
    }

    /// Reverts the latest edit on `image`; returns the changed rectangle.
    pub fn undo(&mut self, image: &mut Image) -> Option<PixelRect> {
        let e = self.undo.pop()?;
        for t in &e.tiles {
            paste(image, t.rect, &t.before);
        }
        let r = e.rect;
        self.redo.push(e);
        r
    }

    /// Re-applies the latest undone edit; returns the changed rectangle.
    pub fn redo(&mut self, image: &mut Image) -> Option<PixelRect> {
        let e = self.redo.pop()?;
        for t in &e.tiles {
            paste(image, t.rect, &t.after);
        }
        let r = e.rect;
        self.undo.push(e);
        r
    }

    /// Identifies the current state: the id of the latest applied edit, 0
    /// for the unedited image (two states with the same id are the same image).
    #[must_use]
    pub fn current_id(&self) -> u64 {
        self.undo.last().map_or(0, |e| e.id)
    }

    /// Number of edits that can be undone.
    #[must_use]
    pub fn undo_len(&self) -> usize {
        self.undo.len()
    }

    /// Number of edits that can be redone.
    #[must_use]
    pub fn redo_len(&self) -> usize {
        self.redo.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(w: usize, h: usize) -> Image {
        Image::from_vec(w, h, 2, (0..w * h * 2).map(|i| i as f32).collect()).expect("image")
    }

    fn paint(image: &mut Image, rec: &mut EditRecorder, rect: PixelRect, v: f32) {
        rec.before_change(image, rect);
        let n = rect.area() * image.channels();
        paste(image, rect, &vec![v; n]);
    }

    #[test]
    fn undo_redo_round_trip() {
        let mut im = img(150, 70);
        let original = im.clone();
        let mut h = History::default();
        let a = PixelRect {
            x0: 60,
            y0: 10,
            width: 30,
            height: 60,
        };
        let mut rec = EditRecorder::new(&im);
        paint(&mut im, &mut rec, a, -1.0);
        // Overlapping second dab of the same stroke: tiles already saved.
        paint(
            &mut im,
            &mut rec,
            PixelRect {
                x0: 70,
                y0: 20,
                width: 80,
                height: 5,
            },
            -2.0,
        );
        h.push(rec.finish(&im).expect("edit"));
        let after1 = im.clone();
        let mut rec = EditRecorder::new(&im);
        paint(
            &mut im,
            &mut rec,
            PixelRect {
                x0: 0,
                y0: 0,
                width: 5,
                height: 5,
            },
            -3.0,
        );
        h.push(rec.finish(&im).expect("edit"));
        let after2 = im.clone();
        let id2 = h.current_id();
        assert_eq!(h.undo_len(), 2);
        assert!(h.undo(&mut im).is_some());
        assert_eq!(im.data(), after1.data());
        assert!(h.undo(&mut im).is_some());
        assert_eq!(im.data(), original.data());
        assert_eq!(h.current_id(), 0);
        assert!(h.undo(&mut im).is_none());
        assert!(h.redo(&mut im).is_some());
        assert_eq!(im.data(), after1.data());
        assert!(h.redo(&mut im).is_some());
        assert_eq!(im.data(), after2.data());
        assert_eq!(h.current_id(), id2);
        assert!(h.redo(&mut im).is_none());
        // A new edit after an undo drops the redo branch.
        h.undo(&mut im);
        let mut rec = EditRecorder::new(&im);
        paint(
            &mut im,
            &mut rec,
            PixelRect {
                x0: 100,
                y0: 60,
                width: 3,
                height: 3,
            },
            5.0,
        );
        h.push(rec.finish(&im).expect("edit"));
        assert_eq!(h.redo_len(), 0);
        assert_eq!(h.undo_len(), 2);
    }

    #[test]
    fn memory_limit_drops_oldest() {
        let mut im = img(128, 128);
        let mut h = History::new(3 * TILE * TILE * 2 * 8);
        for k in 0..4 {
            let mut rec = EditRecorder::new(&im);
            paint(
                &mut im,
                &mut rec,
                PixelRect {
                    x0: (k % 2) * 64,
                    y0: (k / 2) * 64,
                    width: 10,
                    height: 10,
                },
                k as f32,
            );
            h.push(rec.finish(&im).expect("edit"));
        }
        assert_eq!(h.undo_len(), 3);
        assert!(EditRecorder::new(&im).finish(&im).is_none());
    }
}
