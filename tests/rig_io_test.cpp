// The rig file format: reading, refusals with JSON paths, round trips.

#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "generate/tube.hpp"
#include "helpers.hpp"

#include <gtest/gtest.h>

#include <sstream>

#include <iomanip>

#include <limits>

using namespace curvenet;

namespace {
std::string minimal(const std::string& extra_top = "", const std::string& node_extra = "") {
  return R"({"format":"curvenet-rig","version":1,)" + extra_top + R"("nodes":[{"id":"a","position":[0,0,0])" +
         node_extra + R"(},{"id":"b","position":[1,0,0]}],
           "profiles":[{"id":"p","from":"a","to":"b","points":[[0,0,0],[1,0,0]]}]})";
}
std::string element_of(const std::string& text) {
  try {
    parse_rig(text, "t.cnrig.json");
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "t.cnrig.json");
    // The JSON path; the line and column follow it, for a person.
    const std::string element = e.element();
    const auto place = element.find(" (line ");
    return place == std::string::npos || element[0] != '/' ? element : element.substr(0, place);
  }
  return "(accepted)";
}
} // namespace

TEST(RigIo, ReadsTheWorkedExample) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const Rig rig = read_rig(test::data("xr_tools_hand/example/hand_l.cnrig.json"));
  EXPECT_EQ(rig.nodes.size(), 64u);
  EXPECT_EQ(rig.profiles.size(), 104u);
  EXPECT_EQ(rig.joints.size(), 26u);
  EXPECT_EQ(rig.weights.size(), 64u);
  EXPECT_EQ(rig.coverage, Coverage::Full);
}

TEST(RigIo, AFrameIsASimilarityAtAnyScale) {
  // A uniform scale of 1e154 squared overflowed, and was refused as "not a
  // similarity"; a shear is refused at any scale.
  for (const double s : {1e-200, 1.0, 1e154, 1e300}) {
    std::ostringstream frame;
    frame << std::setprecision(17) << R"("frame":[)" << s << ",0,0,0, 0," << s << ",0,0, 0,0," << s << ",0, 0,0,0,1],";
    EXPECT_EQ(element_of(minimal(frame.str())), "(accepted)") << s;
    std::ostringstream shear;
    shear << std::setprecision(17) << R"("frame":[)" << s << "," << s << ",0,0, 0," << s << ",0,0, 0,0," << s
          << ",0, 0,0,0,1],";
    EXPECT_EQ(element_of(minimal(shear.str())), "/frame") << s;
  }
}

TEST(RigIo, RoundTripsEveryCurveForm) {
  Rig rig = make_tube_net();
  rig.profiles[0].curve.kind = Curve::Kind::Bezier;
  rig.profiles[0].curve.points.resize(7);
  rig.profiles[1].curve = {
      Curve::Kind::Nurbs, {{0, 0, 0}, {1, 1, 0}, {2, 1, 0}, {3, 0, 0}}, 3, {0, 0, 0, 0, 1, 1, 1, 1}, {1, 2, 2, 1}};
  rig.weights["ring0_0"] = {{"root", 0.25}, {"mid", 0.75}};
  const Rig back = parse_rig(rig_to_json(rig), "mem");
  ASSERT_EQ(back.profiles.size(), rig.profiles.size());
  EXPECT_EQ(back.profiles[0].curve.kind, Curve::Kind::Bezier);
  EXPECT_EQ(back.profiles[1].curve.knots, rig.profiles[1].curve.knots);
  EXPECT_EQ(back.profiles[1].curve.weights, rig.profiles[1].curve.weights);
  EXPECT_EQ(back.nodes[3].position, rig.nodes[3].position);
  EXPECT_EQ(back.joints[2].bind, rig.joints[2].bind);
  EXPECT_EQ(back.weights.at("ring0_0").at("mid"), 0.75);
}

TEST(RigIo, AcceptsExtensionsAndMayaKnots) {
  EXPECT_EQ(element_of(minimal(R"("x_tool":{"any":1},)", R"(,"x_note":"hi")")), "(accepted)");
  const Rig r = parse_rig(
      R"({"format":"curvenet-rig","version":1,"nodes":[{"id":"a","position":[0,0,0]},{"id":"b","position":[3,0,0]}],
    "profiles":[{"id":"p","from":"a","to":"b","nurbs":{"degree":3,"points":[[0,0,0],[1,1,0],[2,1,0],[3,0,0]],"knots":[0,0,0,1,1,1]}}]})",
      "maya");
  EXPECT_EQ(r.profiles[0].curve.knots.size(), 8u);
}

TEST(RigIo, RefusesWithTheJsonPathOfTheFault) {
  EXPECT_EQ(
      element_of(
          R"({"format":"curvenet-rig","version":1,"nodes":[{"id":"a","position":[0,0,0]},{"id":"a","position":[1,0,0]}],"profiles":[]})"),
      "/nodes/1/id");
  EXPECT_EQ(element_of(R"({"format":"curvenet-rig","version":1,"nodes":[{"id":"a","position":[0,0,0]}],
      "profiles":[{"id":"p","from":"a","to":"zz","points":[[0,0,0],[1,0,0]]}]})"),
            "/profiles/0/to");
  EXPECT_EQ(element_of(R"({"format":"curvenet-rig","version":1,"nodes":[{"id":"a","position":[0,0,0]}],
      "profiles":[{"id":"p","from":"a","to":"a","points":[[0,0,0],[1,0,0],[0,1,0]]},{"id":"p","from":"a","to":"a","points":[[0,0,0],[1,0,0],[0,1,0]]}]})"),
            "/profiles/1/id");
  EXPECT_EQ(element_of(minimal(R"("colour":"red",)")), "/colour");
  EXPECT_EQ(element_of(minimal("", R"(,"weight":1)")), "/nodes/0/weight");
  EXPECT_EQ(element_of(minimal(R"("frame":[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,1,1],)")), "/frame");
  EXPECT_EQ(element_of(minimal(
                R"("skeleton":{"joints":[{"name":"r","parent":null,"bind":[1,0,0,0,0,1,0,0,0,0,1,0,1,0,0,1]}]},)")),
            "/skeleton/joints/0/bind");
  EXPECT_EQ(element_of(minimal(
                R"("skeleton":{"joints":[{"name":"c","parent":"r","bind":[1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1]}]},)")),
            "/skeleton/joints/0/parent");
  EXPECT_EQ(element_of(minimal(R"("weights":{"a":{"nojoint":1}},)")), "/weights/a/nojoint");
  EXPECT_EQ(element_of(R"({"format":"curvenet-rig","version":2,"nodes":[],"profiles":[]})"), "/version");
}

TEST(RigIo, MalformedJsonNamesTheLine) {
  EXPECT_EQ(element_of("{\n  \"format\": \"curvenet-rig\",\n  \"version\": 1,,\n}"), "line 3, column 16");
}

TEST(RigIo, TheTextItselfIsCheckedWithLinesAndColumns) {
  // Malformed, a number out of range, a key twice: the line and column.
  EXPECT_EQ(element_of("{\"format\":\"curvenet-rig\",\n \"version\":1,\n \"nodes\":["), "line 3, column 11");
  EXPECT_EQ(element_of(minimal("", R"(,"x_big":1e999)")), "line 1, column 84");
  EXPECT_EQ(element_of(minimal("", R"(,"id":"again")")), "/nodes/0/id");
  // Integers are integers in range: 2^32 + 1 is not version 1.
  EXPECT_EQ(element_of(R"({"format":"curvenet-rig","version":4294967297,"nodes":[],"profiles":[]})"), "/version");
  EXPECT_EQ(element_of(R"({"format":"curvenet-rig","version":1.0,"nodes":[],"profiles":[]})"), "/version");
}

TEST(RigIo, MatricesThatWouldGiveNaNAreRefused) {
  // A singular bind matrix, and a frame that is not a similarity.
  EXPECT_EQ(element_of(R"({"format":"curvenet-rig","version":1,"nodes":[],"profiles":[],"skeleton":{"joints":[
      {"name":"j","parent":null,"bind":[1,0,0,0, 0,0,0,0, 0,0,1,0, 0,0,0,1]}]}})"),
            "/skeleton/joints/0/bind");
  EXPECT_EQ(element_of(R"({"format":"curvenet-rig","version":1,"frame":[2,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1],
      "nodes":[],"profiles":[]})"),
            "/frame");
  // A rotation, a uniform scale and a translation are a similarity.
  EXPECT_EQ(element_of(R"({"format":"curvenet-rig","version":1,"frame":[0,-2,0,5, 2,0,0,0, 0,0,2,1, 0,0,0,1],
      "nodes":[],"profiles":[]})"),
            "(accepted)");
}

TEST(RigIo, NothingNonFiniteIsWritten) {
  Rig rig = parse_rig(minimal(), "t.cnrig.json");
  rig.nodes[0].position.x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(rig_to_json(rig), Error);
}

TEST(RigIo, AFaultNamesItsPathLineAndColumn) {
  try {
    parse_rig("{\"format\":\"curvenet-rig\",\"version\":1,\n\"nodes\":[{\"id\":\"a\",\"position\":[0,0,0]},\n "
              "{\"id\":\"a\",\"position\":[1,0,0]}],\"profiles\":[]}",
              "t.cnrig.json");
    FAIL() << "a duplicate node id was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.element(), "/nodes/1/id (line 3, column 3)");
  }
}
