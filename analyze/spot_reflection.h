#pragma once

// Is a spot a reflection? A shiny surface (bare or galvanised metal, glazing, gloss paint)
// reflects into the camera whatever lies in its mirror direction, and the reading shows it
// as a warm patch that is not the surface's own temperature: the thermographer's classic
// false spot is his own body, seen where he looks at a shiny surface head-on, or a hot pipe
// mirrored in polished cladding. A reflection stays put only while the camera does, so a
// thermographer re-images a suspicious spot from another angle. A reconstructed model knows
// where every region was seen from (temperature_view_x/_y/_z, the mean vector to the thermal
// camera) and its normal, so the mirror direction can be traced for every face of a spot:
// - the operator: the mirror ray returns to within operator_radius_m of the camera's centre
//   (the person holding the rig stands there) before meeting a surface, and the spot is no
//   warmer than a person can look (operator_max_c);
// - a hotter surface: the mirror ray meets the model where it is at least as warm as the
//   spot's peak (a reflection reads between the surface's own and the source's temperature).
// A spot whose faces, by area, meet such a source over at least min_fraction of the area
// that has a view vector is a possible reflection: it is still reported, with the source,
// and its suggested action asks for a second view before acting. Meshes without view
// vectors (fixture truth, other tools' PLYs) are not checked.

#include <string>
#include <vector>

#include "analyze/render.h"
#include "analyze/spot.h"
#include "analyze/thermal_mesh.h"

namespace hw::analyze {

struct ReflectionOptions {
  bool check = true;  // false: no spot is checked
  // Radius around the thermal camera's centre taken by the operator's body, m, (0, 5]. 0.6:
  // a rig held at the chest or face has head, shoulders and torso within about 0.6 m of it.
  double operator_radius_m = 0.6;
  // Warmest a person looks to the camera, °C, (-50, 100]. 37: skin under clothing is at most
  // body temperature, and a reflection reads below its source; a spot peaking above this is
  // not the operator.
  double operator_max_c = 37;
  // Fraction of a spot's checked area whose mirror direction meets a source for the spot to
  // be a possible reflection, (0, 1]. 0.5: most of it.
  double min_fraction = 0.5;
  // Faces traced per spot at most (evenly thinned beyond), >= 1: the fraction to a few per
  // cent on spots of any size.
  int max_faces = 2000;

  // "" or a message naming the field, its value and the constraint.
  std::string Check() const;
};

// Traces the mirror direction of every face (at most options.max_faces, evenly thinned) of
// each spot in *spots and fills its reflection fields (Spot::reflection_*, incidence_deg,
// possible_reflection; an unflagged spot's action is unchanged, a flagged one's gets the
// verification first). `renderer` must be built on `mesh`. Does nothing when
// options.check is false or the mesh has no view vectors. Asserts options.Check() == "".
void CheckReflections(const ThermalMesh& mesh, const MeshRenderer& renderer, const ReflectionOptions& options,
                      std::vector<Spot>* spots);

// The warning a flagged spot gets, one line: its id, the fraction, the source (the
// thermographer, with the incidence and peak that make it one, or the surface's temperature
// and place, world frame) and "re-image it from another angle before acting". For a spot
// with possible_reflection set.
std::string ReflectionWarning(const Spot& spot);

}  // namespace hw::analyze
