//! One folder per job kind: parameters, algorithm, tests. Pure computation.

pub mod bulldoze;
pub mod carve_coast;
pub mod deform_terrain;
pub mod erode;
pub mod grow_cave;
pub mod weather_column;

#[cfg(test)]
mod generator_tests;
#[cfg(test)]
mod test_support;

use crate::jobs::JobKind;

/// Every job kind the service offers. Adding a kind is one line here.
pub fn registry() -> Vec<Box<dyn JobKind>> {
    vec![
        Box::new(crate::jobs::Kind::<bulldoze::Bulldoze>::default()),
        Box::new(crate::jobs::Kind::<deform_terrain::DeformTerrain>::default()),
        Box::new(crate::jobs::Kind::<weather_column::WeatherColumn>::default()),
        Box::new(crate::jobs::Kind::<grow_cave::GrowCave>::default()),
        Box::new(crate::jobs::Kind::<carve_coast::CarveCoast>::default()),
        Box::new(crate::jobs::Kind::<erode::Erode>::default()),
    ]
}
