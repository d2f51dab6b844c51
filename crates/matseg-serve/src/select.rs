//! The segment page's refined selection: positive clicks ("this
//! material") and negative ones ("not that one") on a photo, answered
//! from its cached descriptors by the selection method of
//! `matseg_query::select` (its soft map and its own mask), or saved as
//! `selection.json` (the clicks' descriptors) to apply to other photos.

use crate::app::{ApiError, AppState};
use crate::described::{Described, Turn};
use crate::photos::{checked_radius, described, photo_answer, PhotoRef};
use axum::extract::{Query, State};
use axum::response::Response;
use axum::Json;
use image::RgbImage;
use matseg_image::io::encode_png_rgb;
use matseg_query::select::{Click, SavedSelection, Selection, Selector, MAX_CLICKS};
use serde::Deserialize;
use std::sync::Arc;

/// A photo and the clicks on it.
#[derive(Deserialize)]
pub struct SelectQuery {
    root: String,
    path: String,
    /// `x,y;x,y...`: the material to select (one click at least).
    #[serde(default)]
    positive: String,
    /// `x,y;x,y...`: materials to leave out (none or more).
    #[serde(default)]
    negative: String,
    radius: Option<f32>,
}

/// Points `x,y;x,y...` given as the argument `name` (none when empty).
pub(crate) fn parse_clicks(name: &str, text: &str) -> Result<Vec<(f32, f32)>, ApiError> {
    text.split(';')
        .filter(|p| !p.trim().is_empty())
        .map(|p| {
            let (x, y) = p.split_once(',')?;
            let (x, y): (f32, f32) = (x.trim().parse().ok()?, y.trim().parse().ok()?);
            (x.is_finite() && y.is_finite()).then_some((x, y))
        })
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| ApiError::bad(format!("{name} {text:?}: expected X,Y;X,Y... in pixels")))
}

/// The clicks a query names, checked before the photo is read: one
/// positive at least, [`MAX_CLICKS`] in all at most.
fn clicks_of(query: &SelectQuery) -> Result<Vec<Click>, ApiError> {
    let positive = parse_clicks("positive", &query.positive)?;
    let negative = parse_clicks("negative", &query.negative)?;
    if positive.is_empty() {
        return Err(ApiError::bad(
            "positive: give one positive click at least (the material to select)",
        ));
    }
    let total = positive.len() + negative.len();
    if total > MAX_CLICKS {
        return Err(ApiError::bad(format!(
            "positive, negative: {total} clicks; at most {MAX_CLICKS} in all"
        )));
    }
    let clicks = positive.iter().map(|&(x, y)| Click::positive(x, y));
    Ok(clicks
        .chain(negative.iter().map(|&(x, y)| Click::negative(x, y)))
        .collect())
}

/// The first click outside a photo of `size`, as an error naming its
/// argument.
fn check_inside(clicks: &[Click], size: (u32, u32), name: &str) -> Result<(), ApiError> {
    let (w, h) = (size.0 as f32, size.1 as f32);
    match clicks
        .iter()
        .find(|c| !(0.0..w).contains(&c.x) || !(0.0..h).contains(&c.y))
    {
        Some(c) => Err(ApiError::bad(format!(
            "{} {},{}: outside {name} ({w}x{h})",
            if c.positive { "positive" } else { "negative" },
            c.x,
            c.y
        ))),
        None => Ok(()),
    }
}

/// A selection's pixels, row by row, as RGB: red = the soft map (0..1 as
/// 0..255), green = 255 where the method's mask is set, blue = 0.
fn selection_rgb(selection: &Selection) -> Vec<u8> {
    selection
        .soft
        .iter()
        .zip(&selection.mask)
        .flat_map(|(&s, &m)| [(s.clamp(0.0, 1.0) * 255.0).round() as u8, 255 * m as u8, 0])
        .collect()
}

/// A selection as an RGB PNG of its size ([`selection_rgb`]).
pub fn selection_png(selection: &Selection) -> Vec<u8> {
    let (w, h) = (selection.width as u32, selection.height as u32);
    let raw = selection_rgb(selection);
    encode_png_rgb(&RgbImage::from_raw(w, h, raw).expect("one value per pixel"))
}

/// A selection on a described photo as an RGB PNG of the photo's own size
/// ([`selection_rgb`]).
fn selection_png_on(selection: &Selection, described: &Described) -> Vec<u8> {
    if !described.shrunk() {
        return selection_png(selection);
    }
    let raw = described.at_photo_size(selection_rgb(selection), 3);
    let (w, h) = (described.width, described.height);
    encode_png_rgb(&RgbImage::from_raw(w, h, raw).expect("one value per pixel"))
}

/// The photo a select request names, described (with the turn it was
/// described in, if it was now), and its clicks, checked against it; the
/// disc radius.
async fn described_clicks(
    state: &Arc<AppState>,
    query: SelectQuery,
) -> Result<((Arc<Described>, Option<Turn>), Vec<Click>, f32), ApiError> {
    let clicks = clicks_of(&query)?;
    let radius = checked_radius(query.radius)?;
    let photo = PhotoRef {
        root: query.root,
        path: query.path,
    };
    let described = described(state, &photo).await?;
    check_inside(
        &clicks,
        (described.0.width, described.0.height),
        &photo.path,
    )?;
    Ok((described, clicks, radius))
}

/// A selector on `described` with `clicks` added (following the photo's
/// edges and colours), sharing the photo's preparation; the clicks and the
/// radius are in the photo's own pixels.
fn selector_with(
    described: &Described,
    clicks: Vec<Click>,
    radius: f32,
) -> Result<Selector<'_>, ApiError> {
    let bad = |e: matseg_query::select::SelectError| ApiError::bad(e.to_string());
    let photo = Some(&described.photo);
    let radius = described.radius(radius);
    let mut selector =
        Selector::with_prep(&described.map, photo, radius, described.prep.clone()).map_err(bad)?;
    for click in clicks {
        let (x, y) = described.point(click.x, click.y);
        selector.add(Click { x, y, ..click }).map_err(bad)?;
    }
    Ok(selector)
}

/// `GET /api/select?root=R&path=P&positive=X,Y;...&negative=X,Y;...[&radius=5]`:
/// the selection the clicks make, as [`selection_png`], at the photo's own
/// size.
pub async fn selection(
    State(state): State<Arc<AppState>>,
    Query(query): Query<SelectQuery>,
) -> Result<Response, ApiError> {
    let path = query.path.clone();
    let (described, clicks, radius) = described_clicks(&state, query).await?;
    photo_answer(&state, described, &path, true, move |described| {
        let selector = selector_with(described, clicks, radius)?;
        let selection = selector
            .selection()
            .map_err(|e| ApiError::bad(e.to_string()))?;
        Ok(selection_png_on(&selection, described))
    })
    .await
}

/// `GET /api/select/save?root=R&path=P&positive=X,Y;...&negative=X,Y;...[&radius=5]`:
/// the clicks' descriptors and colour features and the served model's
/// name, as `selection.json` holds them.
pub async fn save(
    State(state): State<Arc<AppState>>,
    Query(query): Query<SelectQuery>,
) -> Result<Json<SavedSelection>, ApiError> {
    let ((described, _), clicks, radius) = described_clicks(&state, query).await?;
    let selector = selector_with(&described, clicks, radius)?;
    Ok(Json(selector.saved(state.model.name())))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn query(positive: &str, negative: &str) -> SelectQuery {
        SelectQuery {
            root: "photos".into(),
            path: "coffee.jpg".into(),
            positive: positive.into(),
            negative: negative.into(),
            radius: None,
        }
    }

    fn refusal(positive: &str, negative: &str) -> String {
        let error = clicks_of(&query(positive, negative)).unwrap_err();
        assert_eq!(error.status(), axum::http::StatusCode::BAD_REQUEST);
        format!("{error:?}")
    }

    #[test]
    fn clicks_are_parsed_positive_first() {
        let clicks = clicks_of(&query("1,2;3.5, 4", "5,6")).unwrap();
        assert_eq!(
            clicks,
            [
                Click::positive(1.0, 2.0),
                Click::positive(3.5, 4.0),
                Click::negative(5.0, 6.0)
            ]
        );
    }

    #[test]
    fn bad_clicks_are_refused_naming_the_argument() {
        assert!(refusal("", "5,6").contains("positive: give one"));
        assert!(refusal("1,2", "x,6").contains("negative \\\"x,6\\\""));
        assert!(refusal("NaN,2", "").contains("positive"));
        let many = vec!["1,1"; MAX_CLICKS].join(";");
        assert!(refusal(&many, "2,2").contains("256 clicks"));
        let outside = [Click::positive(1.0, 1.0), Click::negative(3.0, 5.0)];
        let error = check_inside(&outside, (10, 5), "a.png").unwrap_err();
        assert!(format!("{error:?}").contains("negative 3,5: outside a.png (10x5)"));
        assert!(check_inside(&outside[..1], (10, 5), "a.png").is_ok());
    }

    #[test]
    fn the_png_carries_the_soft_map_and_the_mask() {
        let selection = Selection {
            width: 2,
            height: 1,
            soft: vec![0.5, 1.2],
            mask: vec![false, true],
        };
        let png = image::load_from_memory(&selection_png(&selection))
            .unwrap()
            .to_rgb8();
        assert_eq!(png.get_pixel(0, 0).0, [128, 0, 0]);
        assert_eq!(png.get_pixel(1, 0).0, [255, 255, 0]);
    }
}
