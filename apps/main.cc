#include <cstdio>
int main() { std::fprintf(stderr, "mbdae: not built yet\n"); return 1; }
