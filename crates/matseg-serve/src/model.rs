//! The served model, shared by the pages' clicks and the background jobs
//! (evaluations, tracks): clicks go first. A click that needs a photo
//! described is counted while it waits for the model and while it holds
//! it; a background job takes the model for its next image or frame only
//! when no click is counted, so a click waits for at most the one image a
//! job is describing, not for every image the job would take in a row
//! (the model's lock alone lets the job take it again before the woken
//! click runs). A job holds the model only for the net's pass, not while
//! the pass is made into a map at the photo's size.

use image::RgbImage;
use matseg_net::infer::{pixel_map, NetModel};
use matseg_pipeline::segment::describe;
use matseg_pipeline::track::FrameDescriber;
use matseg_query::coarse::CoarseDescriptors;
use matseg_query::descriptor::{Comparison, DescriptorMap, DescriptorModel};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

/// The model and the clicks waiting for it.
pub struct ServedModel {
    net: NetModel,
    clicks: AtomicUsize,
}

impl ServedModel {
    /// `net`, served.
    pub fn new(net: NetModel) -> Self {
        Self {
            net,
            clicks: AtomicUsize::new(0),
        }
    }

    /// The model's name in reports (`default` for the shipped model).
    pub fn name(&self) -> &str {
        self.net.name()
    }

    /// `photo` described for a click, ahead of the background jobs.
    pub fn describe_click(&self, photo: &RgbImage) -> CoarseDescriptors {
        self.clicks.fetch_add(1, Ordering::SeqCst);
        let described = describe(&self.net.lock(), photo);
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
        let grid = self.net.lock().photo_grid(image);
        // Made into a map at the photo's size without holding the net.
        pixel_map(&grid, image.width() as usize, image.height() as usize)
    }
}

/// The model as a track follows frames with it: each frame after the
/// clicks.
impl FrameDescriber for ServedModel {
    fn describe_frame(&self, frame: &RgbImage, side: u32) -> CoarseDescriptors {
        self.let_clicks_pass();
        self.net.describe_frame(frame, side)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;

    fn served() -> ServedModel {
        let net = NetModel::load(std::path::Path::new("default"), Default::default()).unwrap();
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
