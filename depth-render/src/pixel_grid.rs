//! Neighbourhoods on row-major pixel grids, shared by the sensor model and the mask errors.

use rayon::prelude::*;

/// The indices of the 4-neighbours of pixel `i` that lie in a grid of `width` columns and `rows`
/// rows.
pub(crate) fn four_neighbours(i: usize, width: usize, rows: usize) -> impl Iterator<Item = usize> {
    let (u, v) = (i % width, i / width);
    [
        (u.wrapping_sub(1), v),
        (u + 1, v),
        (u, v.wrapping_sub(1)),
        (u, v + 1),
    ]
    .into_iter()
    .filter(move |&(x, y)| x < width && y < rows)
    .map(move |(x, y)| y * width + x)
}

/// `mask` (`width` columns; a partial last row is dropped unless `radius` is 0) dilated (`grow`) or eroded by a (2r + 1)² square,
/// separably (rows, then columns); pixels beyond the grid count as outside the mask.
pub(crate) fn morph(mask: &[bool], width: usize, radius: usize, grow: bool) -> Vec<bool> {
    if radius == 0 {
        return mask.to_vec();
    }
    let rows = mask.len() / width;
    let pass = |input: &[bool], horizontal: bool| -> Vec<bool> {
        (0..input.len())
            .into_par_iter()
            .map(|i| {
                let (u, v) = (i % width, i / width);
                let (position, length) = if horizontal { (u, width) } else { (v, rows) };
                let window = position as i64 - radius as i64..=(position + radius) as i64;
                let mut values = window.map(|p| {
                    (0..length as i64).contains(&p)
                        && if horizontal {
                            input[v * width + p as usize]
                        } else {
                            input[p as usize * width + u]
                        }
                });
                if grow {
                    values.any(|m| m)
                } else {
                    values.all(|m| m)
                }
            })
            .collect()
    };
    pass(&pass(&mask[..rows * width], true), false)
}
