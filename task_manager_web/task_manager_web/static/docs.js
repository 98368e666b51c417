// Swagger UI of the gateway's OpenAPI description, at /docs (a file, not an inline script: the
// Content-Security-Policy allows no inline script).
'use strict';

window.ui = SwaggerUIBundle({
  url: 'openapi.json',
  dom_id: '#swagger-ui',
  layout: 'BaseLayout',
  deepLinking: true,
  showExtensions: true,
  showCommonExtensions: true,
  presets: [SwaggerUIBundle.presets.apis, SwaggerUIBundle.SwaggerUIStandalonePreset],
  tryItOutEnabled: true,
  persistAuthorization: true,
  filter: true,
  displayRequestDuration: true,
});
