// MarkerNameIndex's known answers: every name finds its own index, unknown
// names find -1, a duplicate keeps its first index, and the previous frame's
// position hint is only a hint (a reordered frame still finds the right names).
#include <catch2/catch.hpp>

#include <string>
#include <vector>

#include "transport/marker_name_index.hpp"

using fabrik::wire::MarkerNameIndex;

TEST_CASE("MarkerNameIndex finds each name's index, -1 for others, the first of a duplicate",
          "[codec][names]") {
  std::vector<std::string> names;
  for (int i = 0; i < 100; ++i) names.push_back("M" + std::to_string(i));
  names.push_back("M7");  // a duplicate of index 7
  const MarkerNameIndex index(names);
  for (int i = 0; i < 100; ++i) CHECK(index.find(names[static_cast<std::size_t>(i)]) == i);
  CHECK(index.find("M7") == 7);
  CHECK(index.find("M100") == -1);
  CHECK(index.find("") == -1);
  CHECK(index.find("M") == -1);
}

TEST_CASE("MarkerNameIndex's position hints never give a wrong index", "[codec][names]") {
  const std::vector<std::string> names = {"LASI", "RASI", "LPSI", "RPSI", "LKNE"};
  MarkerNameIndex index(names);
  const std::vector<std::string> frame1 = {"LASI", "RASI", "LPSI", "RPSI", "LKNE"};
  const std::vector<std::string> frame2 = {"RPSI", "XTRA", "LASI", "LKNE", "RASI", "LPSI"};
  for (const auto* frame : {&frame1, &frame1, &frame2, &frame2, &frame1}) {
    for (std::size_t k = 0; k < frame->size(); ++k) {
      const std::string& name = (*frame)[k];
      INFO(name << " at " << k);
      CHECK(index.find_at(k, name) == index.find(name));
    }
  }
  CHECK(index.find_at(0, "RPSI") == 3);
}
