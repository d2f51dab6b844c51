//! The query arguments `segment`, `track` and `eval masks` share: points
//! (grouped into materials or not) and the radius of their discs, parsed
//! and checked once.

use matseg_query::descriptor::check_radius;

/// A point `X,Y` in pixels (a negative coordinate is taken as a value, and
/// refused later as outside the photo, rather than as an unknown option).
#[cfg(feature = "infer")]
pub fn parse_point(s: &str) -> Result<(f32, f32), String> {
    let (x, y) = s
        .split_once(',')
        .ok_or_else(|| format!("{s}: expected X,Y"))?;
    let number = |v: &str| {
        v.trim()
            .parse::<f32>()
            .ok()
            .filter(|n| n.is_finite())
            .ok_or_else(|| format!("{s}: expected X,Y numbers"))
    };
    Ok((number(x)?, number(y)?))
}

/// A point of a material `[GROUP:]X,Y`: points that share a group
/// number are one material; a point without one is a material of its own.
#[cfg(feature = "infer")]
pub fn parse_grouped_point(s: &str) -> Result<(Option<u32>, (f32, f32)), String> {
    match s.split_once(':') {
        None => Ok((None, parse_point(s)?)),
        Some((group, point)) => {
            let group = group
                .trim()
                .parse::<u32>()
                .map_err(|_| format!("{s}: expected GROUP:X,Y with a group number"))?;
            Ok((Some(group), parse_point(point)?))
        }
    }
}

/// A disc radius in pixels, within the range every front end accepts.
pub fn parse_radius(s: &str) -> Result<f32, String> {
    let radius: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s}: expected a number of pixels"))?;
    check_radius(radius).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(feature = "infer")]
    #[test]
    fn points_are_two_finite_numbers() {
        assert_eq!(parse_point("3,4.5"), Ok((3.0, 4.5)));
        assert_eq!(parse_point(" -5 , 10"), Ok((-5.0, 10.0)));
        for bad in ["3", "a,b", "NaN,1", "1,inf", ""] {
            assert!(parse_point(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_grouped_point("3,4"), Ok((None, (3.0, 4.0))));
        assert_eq!(parse_grouped_point("2:3,-4"), Ok((Some(2), (3.0, -4.0))));
        for bad in ["x:3,4", "-1:3,4", "1:3", ":3,4"] {
            assert!(parse_grouped_point(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn radii_are_checked() {
        assert_eq!(parse_radius("5"), Ok(5.0));
        assert_eq!(parse_radius("0"), Ok(0.0));
        for bad in ["-1", "NaN", "1e9", "inf", "five"] {
            assert!(parse_radius(bad).is_err(), "{bad}");
        }
    }
}
