// The translation unit that builds the precompiled header (see CMakeLists.txt, FELT_PCH).
