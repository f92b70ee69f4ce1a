// The API's docs page (/docs): Swagger UI from the daemon's own files, reading /openapi.json.
window.ui = SwaggerUIBundle({ url: "/openapi.json", dom_id: "#swagger-ui", deepLinking: true });
