// disc_ao: one point per disc (obs_disc: centroid and area, normal and squared reach), handed to
// the geometry shader as it is.
#version 450
layout(location = 0) in vec4 in_c;
layout(location = 1) in vec4 in_n;
layout(location = 0) out vec4 v_c;
layout(location = 1) out vec4 v_n;

void main() {
  v_c = in_c;
  v_n = in_n;
  gl_Position = vec4(0.0, 0.0, 0.0, 1.0);
}
