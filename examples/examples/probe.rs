fn main() {
    let grid = so3_grid::Grid::new(4).unwrap();
    let cells = grid.rotations();
    let random = so3_grid::random_rotations(294_912, 1);
    let to = so3_grid::random_rotations(200, 4);
    for _ in 0..3 {
        let t = std::time::Instant::now();
        let a = metrics::nearest_distances(&cells, &to);
        let e1 = t.elapsed();
        let t = std::time::Instant::now();
        let b = metrics::nearest_distances(&random, &to);
        println!(
            "grid cells {:?} random {:?} {} {}",
            e1,
            t.elapsed(),
            a[0],
            b[0]
        );
    }
}
