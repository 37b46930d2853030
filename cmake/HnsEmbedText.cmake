# cmake -DINPUT=file -DOUTPUT=file.cpp -DSYMBOL=name -P HnsEmbedText.cmake
# Writes a C++ source defining `extern const char hns::tools::<SYMBOL>[]` with the text of INPUT.
file(READ "${INPUT}" content)
string(FIND "${content}" ")hnsembed\"" clash)
if(NOT clash EQUAL -1)
  message(FATAL_ERROR "${INPUT} contains the raw-string delimiter )hnsembed\"")
endif()
file(WRITE "${OUTPUT}.tmp"
  "// Generated from ${INPUT} by cmake/HnsEmbedText.cmake. Do not edit.\n"
  "namespace hns::tools {\n"
  "extern const char ${SYMBOL}[];\n"
  "const char ${SYMBOL}[] = R\"hnsembed(${content})hnsembed\";\n"
  "}  // namespace hns::tools\n")
file(RENAME "${OUTPUT}.tmp" "${OUTPUT}")
