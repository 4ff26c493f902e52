// Host test runner: host_tests VECTORS_JSON REFERENCE_DIR (the golden CSVs,
// tests/data/reference in the repository)
#include "minitest.h"
#include "support.h"

int main(int argc, char** argv) {
  if (argc > 1) support::g_vectors_path = argv[1];
  if (argc > 2) support::g_reference_dir = argv[2];
  return minitest::run_all();
}
