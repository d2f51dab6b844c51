//! The served model, shared by the pages' clicks and the background jobs
//! (evaluations, tracks): clicks go first. The net makes one pass at a
//! time (its lock), so concurrent requests hold one pass's memory, not
//! one per request. A click that needs a photo described is counted while
//! it waits for the lock and while it holds it; a background job takes the
//! lock for its next image or frame only when no click is counted, so a
//! click waits for at most the one image a job is describing, not for
//! every image the job would take in a row (the lock alone lets the job
//! take it again before the woken click runs). A job holds the lock only
//! for the net's pass, not while the pass is made into a map at the
//! photo's size.

use image::RgbImage;
use matseg_pipeline::segment::{describe, Model};
use matseg_pipeline::track::FrameDescriber;
use matseg_query::coarse::CoarseDescriptors;
use matseg_query::descriptor::{Comparison, DescriptorMap, DescriptorModel};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Duration;

/// The model and the clicks waiting for it.
pub struct ServedModel {
    net: Model,
    /// Held for each pass of the net.
    pass: Mutex<()>,
    clicks: AtomicUsize,
    /// The longest side the net sees a photo at (`None`: as it is).
    side: Option<u32>,
    /// Values of each descriptor.
    dim: usize,
}

impl ServedModel {
    /// `net`, served.
    pub fn new(net: Model) -> Self {
        let (side, dim) = (net.net().inference_side(), net.net().output_dim());
        Self {
            net,
            pass: Mutex::new(()),
            clicks: AtomicUsize::new(0),
            side,
            dim,
        }
    }

    /// The bytes a description of a photo described at `size` will hold
    /// ([`Described::bytes`](crate::described::Described::bytes)) at
    /// most, known before it is made: the net's grid is a quarter of the
    /// photo shrunk to the inference side, each side rounded to a multiple
    /// of 32.
    pub fn described_bytes(&self, size: (u32, u32)) -> usize {
        let longer = size.0.max(size.1).max(1) as f64;
        let shrink = self
            .side
            .map_or(1.0, |side| (side as f64 / longer).min(1.0));
        let cells = |n: u32| ((n as f64 * shrink).round() as usize + 32) / 4 + 1;
        crate::described::bytes_held(size, cells(size.0) * cells(size.1), self.dim)
    }

    /// The model's name in reports (`default` for the shipped model).
    pub fn name(&self) -> &str {
        self.net.name()
    }

    /// `photo` described for a click, ahead of the background jobs.
    pub fn describe_click(&self, photo: &RgbImage) -> CoarseDescriptors {
        self.clicks.fetch_add(1, Ordering::SeqCst);
        let described = {
            let _pass = matseg_image::sync::lock(&self.pass);
            describe(&self.net, photo)
        };
        self.clicks.fetch_sub(1, Ordering::SeqCst);
        described
    }

    /// Waits while any click wants the model: what a background job does
    /// before each image or frame.
    fn let_clicks_pass(&self) {
        while self.clicks.load(Ordering::SeqCst) > 0 {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
}

/// The model as an evaluation scores it: each image after the clicks.
impl DescriptorModel for ServedModel {
    fn name(&self) -> &str {
        self.net.name()
    }

    fn comparison(&self) -> Comparison {
        self.net.comparison()
    }

    fn describe(&self, image: &RgbImage) -> DescriptorMap {
        self.let_clicks_pass();
        let grid = {
            let _pass = matseg_image::sync::lock(&self.pass);
            self.net.net().photo_grid(image)
        };
        // Made into a map at the photo's size without holding the net.
        grid.pixel_map(image.width() as usize, image.height() as usize)
    }
}

/// The model as a track follows frames with it: each frame after the
/// clicks.
impl FrameDescriber for ServedModel {
    fn describe_frame(&self, frame: &RgbImage, side: u32) -> CoarseDescriptors {
        self.let_clicks_pass();
        let _pass = matseg_image::sync::lock(&self.pass);
        self.net.describe_frame(frame, side)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;

    fn served() -> ServedModel {
        let net = matseg_pipeline::segment::load_model(
            std::path::Path::new("default"),
            Default::default(),
        )
        .unwrap();
        ServedModel::new(net)
    }

    #[test]
    fn an_evaluation_gets_the_maps_the_command_line_gets() {
        let model = served();
        let photo = matseg_image::io::read_rgb(
            &matseg_pipeline::sources::assets_dir().join("photos/coffee.jpg"),
        )
        .unwrap();
        let photo = image::imageops::thumbnail(&photo, 150, 100);
        assert_eq!(
            DescriptorModel::describe(&model, &photo),
            DescriptorModel::describe(&model.net, &photo)
        );
    }

    #[test]
    fn a_description_holds_no_more_than_was_counted_for_it() {
        let model = served();
        let coffee = matseg_image::io::read_rgb(
            &matseg_pipeline::sources::assets_dir().join("photos/coffee.jpg"),
        )
        .unwrap();
        for (w, h) in [(600, 400), (150, 100), (1000, 90), (33, 700)] {
            let photo =
                image::imageops::resize(&coffee, w, h, image::imageops::FilterType::Triangle);
            let map = model.describe_click(&photo);
            let described = crate::described::Described::new(photo, map, (w, h));
            let counted = model.described_bytes((w, h));
            assert!(
                described.bytes() <= counted,
                "{w}x{h}: {} > {counted}",
                described.bytes()
            );
            assert!(
                described.bytes() * 2 >= counted,
                "{w}x{h}: counted far too much"
            );
        }
    }

    #[test]
    fn background_work_waits_while_a_click_is_counted() {
        let model = Arc::new(served());
        let passed = Arc::new(AtomicBool::new(false));
        model.clicks.fetch_add(1, Ordering::SeqCst);
        let background = {
            let (model, passed) = (model.clone(), passed.clone());
            std::thread::spawn(move || {
                model.let_clicks_pass();
                passed.store(true, Ordering::SeqCst);
            })
        };
        std::thread::sleep(Duration::from_millis(100));
        assert!(!passed.load(Ordering::SeqCst), "passed a counted click");
        model.clicks.fetch_sub(1, Ordering::SeqCst);
        background.join().unwrap();
        assert!(passed.load(Ordering::SeqCst));
    }
}
