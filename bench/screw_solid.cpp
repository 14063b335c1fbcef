// The true screws of the CAD study (docs/results.md, "A part from its CAD
// file"): Debian's screw.step rebuilt with OpenCASCADE's own operations at
// given values of examples/screw/screw.json's dimensions (occt_solids.h),
// written as STEP and STL, for the replica lab (a recipe's "physical" part)
// and for tools/lab2 (an "stl" solid). No xgauge vertex placement is used.
//
//   screw_solid --set slot_width=2.6 --set length=42.3 --step s.step --stl s.stl
//
// Dimensions not set take their nominal values.
#include "geometry/occt_solids.h"

#include <BRepMesh_IncrementalMesh.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <Message_PrinterOStream.hxx>
#include <STEPControl_Writer.hxx>
#include <StlAPI_Writer.hxx>

#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>

int main(int argc, char** argv) {
  std::map<std::string, double> values = {{"slot_width", 2.5},
                                          {"slot_depth", 5.0},
                                          {"shank_diameter", 10.0},
                                          {"length", 42.5},
                                          {"shank_offset", 0.0}};
  std::string step, stl;
  double chord_mm = 0.0005;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "screw_solid: %s needs a value\n", arg.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (arg == "--set") {
      const std::string pair = next();
      const size_t eq = pair.find('=');
      if (eq == std::string::npos || !values.count(pair.substr(0, eq))) {
        std::fprintf(stderr, "screw_solid: --set %s: expected name=value with a dimension of "
                             "examples/screw/screw.json\n", pair.c_str());
        return 2;
      }
      values[pair.substr(0, eq)] = std::stod(pair.substr(eq + 1));
    } else if (arg == "--step") {
      step = next();
    } else if (arg == "--stl") {
      stl = next();
    } else if (arg == "--chord-tolerance-mm") {
      chord_mm = std::stod(next());
    } else {
      std::fprintf(stderr,
                   "usage: screw_solid [--set name=value]... [--step FILE] [--stl FILE] "
                   "[--chord-tolerance-mm T]\n");
      return 2;
    }
  }
  Message::DefaultMessenger()->RemovePrinters(STANDARD_TYPE(Message_PrinterOStream));
  const TopoDS_Shape screw = xgauge::testing::screwSolid(values);
  if (!step.empty()) {
    STEPControl_Writer writer;
    if (writer.Transfer(screw, STEPControl_AsIs) != IFSelect_RetDone ||
        writer.Write(step.c_str()) != IFSelect_RetDone) {
      std::fprintf(stderr, "screw_solid: cannot write %s\n", step.c_str());
      return 1;
    }
  }
  if (!stl.empty()) {
    const BRepMesh_IncrementalMesh mesh(screw, chord_mm, Standard_False, 0.35, Standard_False);
    StlAPI_Writer writer;
    writer.ASCIIMode() = Standard_False;
    if (!writer.Write(screw, stl.c_str())) {
      std::fprintf(stderr, "screw_solid: cannot write %s\n", stl.c_str());
      return 1;
    }
  }
  return 0;
}
