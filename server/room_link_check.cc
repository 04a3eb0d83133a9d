// The program every room's link check (server/CMakeLists.txt sandswim_room_link_check) links its
// library into, whole: it only has to link, never to run.
int main() { return 0; }
