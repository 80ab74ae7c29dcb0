// Work in progress: filled in by the commit that implements it.
int main() { return 0; }
