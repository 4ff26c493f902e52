// Host test runner: host_tests VECTORS_JSON REFERENCE_DIR [VECTORS_EXT_JSON] (the
// golden CSVs are tests/data/reference in the repository)
#include "minitest.h"
#include "support.h"

int main(int argc, char** argv) {
  if (argc > 1) support::g_vectors_path = argv[1];
  if (argc > 2) support::g_reference_dir = argv[2];
  if (argc > 3) support::g_vectors_ext_path = argv[3];
  return minitest::run_all();
}
