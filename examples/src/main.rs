fn main() {
    for level in 0..5u8 {
        let g = so3_grid::Grid::new(level).unwrap();
        let r = g.rotations();
        let mut worst: f64 = 0.0;
        for q in so3_grid::random_rotations(200000, 1) {
            let c = g.locate(&q).unwrap();
            worst = worst.max(so3_grid::geodesic_distance(&r[c as usize], &q).to_degrees());
        }
        println!("{level} {worst}");
    }
}
