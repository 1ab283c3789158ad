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

// The daemon tells "only another subject's markers" (a split across processes) from a
// misnamed subject by this: a name "X:..." is foreign when no name of the index starts "X:".
TEST_CASE("MarkerNameIndex::foreign: a NAME: prefix none of its names has, nothing else") {
  const std::vector<std::string> names{"Alice:LASI", "Alice:RASI", "Bob:LASI", "C7"};
  const MarkerNameIndex index(names);
  CHECK(index.foreign("Carol:LASI"));
  CHECK(index.foreign("Al:LASI"));           // a prefix of "Alice" is another name
  CHECK(index.foreign("Alice2:LASI"));
  CHECK_FALSE(index.foreign("Alice:TOE"));   // one of ours, misnamed: a mismatch, not foreign
  CHECK_FALSE(index.foreign("Bob:Zed:LASI"));  // the first ':' names the subject
  CHECK_FALSE(index.foreign("LASI"));        // no prefix at all
  CHECK_FALSE(index.foreign(":LASI"));       // an empty prefix is none
  const std::vector<std::string> bare{"LASI", "RASI"};
  CHECK(MarkerNameIndex(bare).foreign("Alice:LASI"));  // bare names: any prefix is another's
}
