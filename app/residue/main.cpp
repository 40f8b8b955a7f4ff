// Placeholder until the viewer lands (issue 4).
int main() { return 0; }
