// InputError: its message composed from the file, the element, the problem and the hint, and each part
// readable on its own (callers that rename the element or the file rethrow from the parts, not from what()).
#include <gtest/gtest.h>
#include <clearfit/error.hpp>

using clearfit::InputError;

TEST(InputError, ComposesItsPartsAndKeepsEachOfThem) {
  const InputError all("scene.yaml", "line 3, key 'ior'", "must be > 1: got 0.9", "the resin's index, e.g. 1.49");
  EXPECT_STREQ(all.what(), "scene.yaml: line 3, key 'ior': must be > 1: got 0.9 (the resin's index, e.g. 1.49)");
  EXPECT_EQ(all.file(), "scene.yaml");
  EXPECT_EQ(all.element(), "line 3, key 'ior'");
  EXPECT_EQ(all.problem(), "must be > 1: got 0.9");  // its own ": " stays in the problem
  EXPECT_EQ(all.hint(), "the resin's index, e.g. 1.49");

  const InputError option("", "--gap-mm", "must be >= 0");
  EXPECT_STREQ(option.what(), "--gap-mm: must be >= 0");
  EXPECT_EQ(option.file(), "");
  EXPECT_EQ(option.hint(), "");

  // Renaming the element (as clearfit board does: gap_mm -> --gap-mm) keeps the rest word for word.
  const InputError key("", "gap_mm", "must be >= 0: got -1", "the gap between tags");
  const InputError renamed("", "--gap-mm", key.problem(), key.hint());
  EXPECT_STREQ(renamed.what(), "--gap-mm: must be >= 0: got -1 (the gap between tags)");

  const InputError bare("", "", "no input");
  EXPECT_STREQ(bare.what(), "no input");
}
