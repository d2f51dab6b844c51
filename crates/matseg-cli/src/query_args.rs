//! The query arguments `segment`, `track` and `eval masks` share: points
//! and the radius of their discs, parsed and checked once.

use matseg_query::descriptor::check_radius;

/// A point `X,Y` in pixels (a negative coordinate is taken as a value, and
/// refused later as outside the photo, rather than as an unknown option).
#[cfg(feature = "net")]
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

    #[cfg(feature = "net")]
    #[test]
    fn points_are_two_finite_numbers() {
        assert_eq!(parse_point("3,4.5"), Ok((3.0, 4.5)));
        assert_eq!(parse_point(" -5 , 10"), Ok((-5.0, 10.0)));
        for bad in ["3", "a,b", "NaN,1", "1,inf", ""] {
            assert!(parse_point(bad).is_err(), "{bad}");
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
