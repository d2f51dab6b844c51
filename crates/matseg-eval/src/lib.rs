//! Evaluation of material descriptors on real photos (pipeline.md §9): point
//! benchmarks in the MatSeg format scored by the triplet metric, mask
//! benchmarks scored by IoU at the best threshold, and training-free
//! baselines behind the same `DescriptorModel` trait (`matseg_query::descriptor`)
//! a trained net implements, and models matseg did not train, scored from
//! their descriptor or similarity maps (files, Python).

#![warn(missing_docs)]

pub mod annotation;
pub mod baselines;
pub mod click_selection;
pub mod clicks;
pub mod evaluate;
pub mod external;
pub mod iou;
pub mod masks;
pub mod model;
pub mod overlay;
pub mod points;
pub mod synthetic;
pub mod template;
pub mod triplet;

pub use annotation::{Annotation, AnnotationProblem, Group, Relation};
pub use evaluate::{
    evaluate_masks, evaluate_points, MaskEvalOptions, MaskEvaluation, MaskReport, PointReport,
};
pub use iou::{best_iou, best_iou_on_grid, BestIou};
pub use masks::{scan_mask_benchmark, MaskImage, QueryOptions};
pub use model::{Answer, ClickAnswer, Described, Question, ScoredModel};
pub use points::{
    is_point_benchmark, load_point_benchmark, BenchError, BenchImage, PointBenchmark,
};
pub use triplet::{score_image, ImageScores, PointScores};
