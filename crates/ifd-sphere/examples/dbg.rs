use ifd_sphere::zhf::*;
fn main() {
    for sh in [Sharing::PerBand, Sharing::Shared] {
        for ch in [Chooser::Fibonacci, Chooser::Random{seed:3}] {
            let d = DirectionSet::new(32, sh, ch).unwrap();
            let c = d.condition_numbers();
            println!("{sh:?} {ch:?} max {:e} {:?}", c.iter().cloned().fold(0.0,f64::max), c.iter().map(|x| format!("{x:.1e}")).collect::<Vec<_>>().join(" "));
        }
    }
}
