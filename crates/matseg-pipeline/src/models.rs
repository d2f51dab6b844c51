//! The descriptor models a front end scores or segments with: baselines
//! by name (colour and texture statistics; with the net, the ImageNet
//! encoder's features) and trained nets by folder, file or `default`.

use crate::error::PipelineError;
use matseg_eval::baselines::{baseline, BASELINES};
use matseg_image::device::ComputeDevice;
use matseg_query::descriptor::DescriptorModel;
use std::path::PathBuf;

/// Which models to build.
#[derive(Clone, Debug)]
pub struct ModelChoice {
    /// Baselines by name (see [`known_baselines`]; `all` for every one).
    pub baselines: Vec<String>,
    /// Trained nets: `default` (the shipped model), run folders or weights
    /// files; `none` stands for no net. A build without the net refuses
    /// any other.
    pub nets: Vec<PathBuf>,
    /// Longer sides the nets describe photos at instead of their runs' own
    /// setting (empty: their own); several sides average the descriptors.
    pub net_sides: Vec<u32>,
    /// The device the nets and the ImageNet baseline run on.
    pub device: ComputeDevice,
}

/// Baseline names, in table order: the colour and texture statistics, then
/// (in a build with inference) the ImageNet features.
pub fn known_baselines() -> Vec<&'static str> {
    [BASELINES.as_slice(), NET_BASELINES].concat()
}

/// The baselines that need an inference engine (none in a build without
/// one).
#[cfg(feature = "infer")]
const NET_BASELINES: &[&str] = &[matseg_model::config::IMAGENET_BASELINE];
#[cfg(not(feature = "infer"))]
const NET_BASELINES: &[&str] = &[];

/// The chosen baselines (in table order), then the nets (each named after
/// its run folder); at least one model.
pub fn models(choice: &ModelChoice) -> Result<Vec<Box<dyn DescriptorModel>>, PipelineError> {
    let mut models = baselines(choice)?;
    models.extend(nets(choice)?);
    if models.is_empty() {
        return Err(PipelineError::Settings(
            "nothing to score: give --baseline NAME... or --model RUN...".into(),
        ));
    }
    Ok(models)
}

/// The chosen baselines alone, in table order (none when none is chosen).
pub fn baselines(choice: &ModelChoice) -> Result<Vec<Box<dyn DescriptorModel>>, PipelineError> {
    let known = known_baselines();
    let mut wanted: Vec<&str> = Vec::new();
    for name in &choice.baselines {
        if name == "all" {
            wanted.extend(&known);
        } else if known.contains(&name.as_str()) {
            wanted.push(name);
        } else {
            return Err(PipelineError::Settings(format!(
                "unknown baseline {name:?}; known: {}, all",
                known.join(", ")
            )));
        }
    }
    let mut models: Vec<Box<dyn DescriptorModel>> = Vec::new();
    for name in known.iter().filter(|b| wanted.contains(b)) {
        match baseline(name) {
            Some(model) => models.push(model),
            #[cfg(feature = "infer")]
            None => models.push(crate::nets::imagenet_baseline(choice.device)?),
            #[cfg(not(feature = "infer"))]
            None => unreachable!("every known baseline is built"),
        }
    }
    Ok(models)
}

/// The chosen trained nets.
#[cfg(feature = "infer")]
fn nets(choice: &ModelChoice) -> Result<Vec<Box<dyn DescriptorModel>>, PipelineError> {
    let mut nets: Vec<Box<dyn DescriptorModel>> = Vec::new();
    for path in choice.nets.iter().filter(|p| p.as_os_str() != "none") {
        let mut net = crate::nets::load_net(path, choice.device)?;
        if let Some((&main, extra)) = choice.net_sides.split_first() {
            net.net_mut()
                .set_inference_sides(Some(main), extra.to_vec());
        }
        nets.push(Box::new(net));
    }
    Ok(nets)
}

/// No trained nets in a build without inference: naming one is refused.
#[cfg(not(feature = "infer"))]
fn nets(choice: &ModelChoice) -> Result<Vec<Box<dyn DescriptorModel>>, PipelineError> {
    match choice.nets.iter().find(|p| p.as_os_str() != "none") {
        Some(path) => Err(PipelineError::setting(
            "model",
            Some(path.display()),
            crate::error::NO_NET,
        )),
        None => Ok(Vec::new()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn choice(baselines: &[&str]) -> ModelChoice {
        ModelChoice {
            baselines: baselines.iter().map(|b| b.to_string()).collect(),
            nets: vec!["none".into()],
            net_sides: Vec::new(),
            device: ComputeDevice::Cpu,
        }
    }

    #[test]
    fn baselines_come_in_table_order_whatever_order_they_are_asked_in() {
        let models = models(&choice(&["texture", "rgb"])).unwrap();
        let names: Vec<String> = models.iter().map(|m| m.name().to_string()).collect();
        assert_eq!(names, vec!["rgb", "texture"]);
    }

    #[test]
    fn unknown_baselines_and_no_models_are_refused() {
        let unknown = models(&choice(&["sift"])).err().expect("refused");
        assert!(unknown
            .to_string()
            .starts_with("unknown baseline \"sift\"; known: rgb, lab"));
        assert!(models(&choice(&[])).is_err());
    }
}
