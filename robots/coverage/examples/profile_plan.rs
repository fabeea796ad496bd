//! Times the planner's phases on an open 60 x 60 vertex map: `cargo run --release -p
//! hetsim-coverage --example profile_plan`.
use hetsim_coverage::select::{select_parent_vertices, tour};
use hetsim_coverage::{plan_with, CoverageParams, Map, Visibility};

#[allow(clippy::disallowed_methods)]
fn main() {
    let rows: Vec<String> = (0..60).map(|_| ".".repeat(60)).collect();
    let refs: Vec<&str> = rows.iter().map(String::as_str).collect();
    let map = Map::from_text(&refs, 0.5);
    let params = CoverageParams::default();
    let t = std::time::Instant::now();
    let vis = Visibility::compute(&map, &params);
    let t_vis = t.elapsed();
    let sel = select_parent_vertices(&map, &vis, &params);
    let t_sel = t.elapsed();
    let _ = tour(&map, &sel.chosen, 1830, Default::default());
    let t_tour = t.elapsed();
    let plan = plan_with(&map, &params, &vis, 1830, &[]).unwrap();
    let t_all = t.elapsed();
    println!("visibility {:?}, selection {:?}, tour {:?}, full plan (again incl. selection+tour+execution) {:?}; |V_p| {}", t_vis, t_sel - t_vis, t_tour - t_sel, t_all - t_tour, plan.parent_vertices.len());
}
