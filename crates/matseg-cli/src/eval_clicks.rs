//! `matseg eval clicks`: how many clicks a selection needs, on a mask
//! benchmark (NoC@85, NoC@90, IoU after 1, 3 and 5 clicks) or a point
//! benchmark (the balanced accuracy of the points not clicked after 1, 3
//! and 5 clicks), for the chosen models (`matseg_eval::clicks`).

use crate::eval::{models, score, ModelArgs};
use anyhow::Result;
use matseg_eval::clicks::{
    evaluate_clicks, evaluate_point_clicks, ClickEvaluation, ClickOptions, ClickReport, Targets,
    LARGE_DROP, REPORTED_CLICKS,
};
use matseg_eval::{is_point_benchmark, load_point_benchmark, scan_mask_benchmark};
use matseg_image::progress::Silent;
use std::path::PathBuf;

/// Arguments of `matseg eval clicks`.
#[derive(clap::Args)]
pub struct Args {
    /// A mask benchmark (NAME.jpg, NAME.mask0.png, ...) or a point
    /// benchmark (images/, data/NAME/data.json).
    data: PathBuf,
    #[command(flatten)]
    model: ModelArgs,
    /// The most clicks a mask gets.
    #[arg(long, default_value_t = 20)]
    max_clicks: usize,
    /// Radius of each click's disc, in pixels.
    #[arg(long, default_value_t = 5.0, value_parser = crate::query_args::parse_radius, allow_negative_numbers = true)]
    radius: f32,
    /// Leave out masks smaller than this many pixels (at the evaluated size).
    #[arg(long, default_value_t = 100)]
    min_area: usize,
    /// Also score targets of two materials: each pair of a photo's masks,
    /// merged (mask benchmarks).
    #[arg(long)]
    unions: bool,
}

/// Runs `matseg eval clicks`.
pub fn run(args: Args) -> Result<()> {
    if args.max_clicks < *REPORTED_CLICKS.iter().max().expect("reported") {
        anyhow::bail!("--max-clicks {}: give 5 at least", args.max_clicks);
    }
    let options = ClickOptions {
        max_side: args.model.max_side,
        max_clicks: args.max_clicks,
        radius: args.radius,
        min_area: args.min_area,
        targets: Targets::Masks,
    };
    let models = models(&args.model)?;
    if is_point_benchmark(&args.data) {
        let bench = load_point_benchmark(&args.data, false)?;
        let reports = models
            .iter()
            .map(|m| evaluate_point_clicks(m.as_ref(), &bench, &options, &Silent))
            .collect::<Result<Vec<_>, _>>()?;
        if reports.first().is_some_and(|r| r.runs.is_empty()) {
            anyhow::bail!(
                "{}: no material could be clicked: no image has a material with points",
                args.data.display()
            );
        }
        if args.model.json {
            let evaluation = ClickEvaluation {
                data: &args.data,
                max_side: options.max_side,
                models: &reports,
                unions: None,
            };
            println!("{}", serde_json::to_string_pretty(&evaluation)?);
            return Ok(());
        }
        println!(
            "{}: {} materials clicked; balanced accuracy of the points not clicked",
            args.data.display(),
            reports.first().map_or(0, |r| r.runs.len())
        );
        println!("| model | after 1 click | after 3 | after 5 |");
        println!("|---|---|---|---|");
        for r in &reports {
            let ba = &r.balanced_accuracy_at;
            println!(
                "| {} | {} | {} | {} |",
                r.model,
                score_at(ba, 1),
                score_at(ba, 3),
                score_at(ba, 5)
            );
        }
        return Ok(());
    }
    let images = scan_mask_benchmark(&args.data)?;
    let score_all = |options: &ClickOptions| {
        models
            .iter()
            .map(|m| evaluate_clicks(m.as_ref(), &images, options, &Silent))
            .collect::<Result<Vec<_>, _>>()
    };
    let reports = score_all(&options)?;
    if let Some(r) = reports.first().filter(|r| r.masks == 0) {
        anyhow::bail!(
            "{}: no mask could be scored: all {} are empty or smaller than --min-area {} pixels at the evaluated size (--max-side {}; masks are read as 8-bit grey, 128 and above inside)",
            args.data.display(),
            r.skipped_masks,
            options.min_area,
            options.max_side
        );
    }
    let unions = if args.unions {
        let unions = ClickOptions {
            targets: Targets::Unions,
            ..options.clone()
        };
        score_all(&unions)?
    } else {
        Vec::new()
    };
    if args.model.json {
        let evaluation = ClickEvaluation {
            data: &args.data,
            max_side: options.max_side,
            models: &reports,
            unions: Some(&unions[..]).filter(|_| args.unions),
        };
        println!("{}", serde_json::to_string_pretty(&evaluation)?);
        return Ok(());
    }
    print_mask_table(&args.data, "masks", &reports, &options);
    if args.unions {
        println!();
        print_mask_table(&args.data, "unions of two masks", &unions, &options);
    }
    Ok(())
}

/// Prints the reports of one kind of target (`what`) as a table, with
/// each model's drops below it.
fn print_mask_table(
    data: &std::path::Path,
    what: &str,
    reports: &[ClickReport],
    options: &ClickOptions,
) {
    println!(
        "{}: {} {what} clicked ({} too small), at most {} clicks each",
        data.display(),
        reports.first().map_or(0, |r| r.masks),
        reports.first().map_or(0, |r| r.skipped_masks),
        options.max_clicks
    );
    println!("| model | NoC@85 | NoC@90 | IoU after 1 click | after 3 | after 5 | one click at the best threshold |");
    println!("|---|---|---|---|---|---|---|");
    for r in reports {
        let m = &r.miou_at;
        println!(
            "| {} | {} | {} | {} | {} | {} | {} |",
            r.model,
            score(r.noc85),
            score(r.noc90),
            score_at(m, 1),
            score_at(m, 3),
            score_at(m, 5),
            score(r.one_click_oracle)
        );
    }
    for r in reports {
        let d = &r.drops;
        let largest = d.largest_at.as_ref().map_or(String::new(), |at| {
            let with = at.with.map_or(String::new(), |o| format!("+{o}"));
            format!(" ({} mask {}{with}, click {})", at.image, at.mask, at.click)
        });
        println!(
            "{}: {} of {} clicks lowered the IoU, by {:.3} on average, {:.3} at most{largest}; {} runs lost more than {LARGE_DROP} from one click",
            r.model, d.lowering, d.clicks, d.mean_drop, d.largest, d.runs_with_large
        );
    }
}

/// The score under click count `k` of a report's per-click means.
fn score_at(map: &std::collections::BTreeMap<String, f64>, k: usize) -> String {
    score(map.get(&k.to_string()).copied())
}
